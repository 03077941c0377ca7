"""Type stubs of the compiled extension ``cordis._cordis`` (re-exported by ``cordis``)."""

import os
from typing import Any, Dict, List, Mapping, Optional, Tuple, Union, final

import numpy as np
import numpy.typing as npt

__version__: str
__all__ = [
    "CordisError",
    "CordisIOError",
    "DivergedError",
    "FormatError",
    "Scene",
    "SceneError",
    "TrajectoryError",
    "__version__",
]

class CordisError(Exception):
    """Base class of every error raised by cordis."""

class SceneError(CordisError):
    """The scene is malformed or inconsistent; ``place`` names the field."""

    place: str
    message: str

class TrajectoryError(CordisError):
    """A trajectory is malformed or does not fit its scene; ``place`` names the frame or row."""

    place: str
    message: str

class FormatError(CordisError):
    """A file or text is not in the format it announces (JSON syntax…)."""

    place: str
    message: str

class DivergedError(CordisError):
    """The simulation left the finite numbers (unstable for this ``dt``)."""

    frame: int
    particle: int
    message: str

class CordisIOError(CordisError, OSError):
    """A file could not be read or written (``errno``, ``strerror``, ``filename`` as OSError)."""

    place: str
    message: str

@final
class Scene:
    """A Cordis-Anima network (particles, link catalogue, links) with its time step.

    Immutable: read one with :meth:`from_json` or :meth:`from_dict`, run it with
    :meth:`simulate`. Equal scenes compare equal; scenes pickle as their JSON text.
    """

    @classmethod
    def from_json(cls, path_or_text: Union[str, "os.PathLike[str]"], /) -> "Scene":
        """Reads a scene from JSON text (a ``str`` starting with ``{`` after blanks) or a file.

        Raises FormatError (bad JSON), SceneError (bad scene), CordisIOError (unreadable file).
        """
    @classmethod
    def from_dict(cls, d: Mapping[str, Any], /) -> "Scene":
        """Reads a scene from a dict shaped like the JSON format (numpy values accepted)."""
    def to_json(self) -> str:
        """The scene as pretty-printed JSON text (``cordis-scene/1``)."""
    def to_dict(self) -> Dict[str, Any]:
        """The scene as a dict of plain Python values (the JSON format's structure)."""
    def simulate(self, frames: int) -> npt.NDArray[np.float64]:
        """Positions for ``frames`` frames, a C-contiguous float64 array ``(frames, N, 3)`` in m.

        Frame 0 is the initial positions. The GIL is released while it runs. Raises
        ValueError for a negative count, MemoryError for one that cannot be allocated and
        DivergedError when the motion leaves the finite numbers.
        """
    def stability(self) -> Dict[str, Any]:
        """The stability report, as ``cordis check`` prints it.

        Keys: ``max_stability_ratio`` (float: the largest per-particle ratio
        q = (dt² K + 2 dt Z) / 4m to the bound, neighbours' motion counted), ``stable``
        (bool, q < 1: the scheme cannot explode), ``worst_particle`` (int or None),
        ``local_max_ratio`` (float, neighbours held fixed), ``max_stable_dt`` (float in s, or
        None when any step passes), ``per_particle`` (list of float, None for fixed ones).
        Raises SceneError for an invalid scene.
        """
    @property
    def dt(self) -> float:
        """Time step, s."""
    @property
    def gravity(self) -> Tuple[float, float, float]:
        """Acceleration of every free particle, m/s²."""
    @property
    def num_particles(self) -> int: ...
    @property
    def num_links(self) -> int:
        """Number of listed links (conditional pairs are not counted)."""
    @property
    def num_types(self) -> int:
        """Number of link types in the catalogue."""
    @property
    def type_names(self) -> List[str]:
        """Names of the catalogue's link types, in file order."""
    @property
    def has_unknowns(self) -> bool:
        """True when some parameter or mass is still to be identified."""
    def __eq__(self, other: object, /) -> bool: ...
    __hash__: None  # type: ignore[assignment]
    def __copy__(self) -> "Scene": ...
    def __deepcopy__(self, memo: Optional[Dict[int, Any]]) -> "Scene": ...
    def __reduce__(self) -> Tuple[Any, Tuple[str]]: ...
