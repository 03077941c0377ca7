"""Type stubs of the compiled extension ``cordis._cordis`` (re-exported by ``cordis``)."""

import os
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union, final

import numpy as np
import numpy.typing as npt

__version__: str
EXAMPLES: Tuple[str, ...]
__all__ = [
    "__version__",
    "CordisError",
    "SceneError",
    "TrajectoryError",
    "FormatError",
    "DivergedError",
    "CheckpointError",
    "CordisIOError",
    "CostKindError",
    "ParamLengthError",
    "Scene",
    "read_trajectory",
    "write_trajectory",
    "example",
    "EXAMPLES",
    "CostReport",
    "Objective",
    "cost",
    "IdentifyResult",
    "identify",
    "DiscoverResult",
    "discover",
    "random_network",
    "_cli_main",
]

_PathLike = Union[str, "os.PathLike[str]"]
_ArrayLike = npt.ArrayLike

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

class CostKindError(CordisError, ValueError):
    """A cost kind that does not parse (``horizon:x``, ``shrt``…); ``place`` quotes it."""

    place: str
    message: str

class ParamLengthError(CordisError, ValueError):
    """A parameter vector or population of the wrong length."""

    place: str
    expected: int
    got: int

class CheckpointError(CordisError):
    """A checkpoint could not be read or written, or does not fit the run it should resume."""

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

def read_trajectory(path: _PathLike, /) -> npt.NDArray[np.float64]:
    """Reads a ``.csv``, ``.npy`` or ``.tra`` trajectory (by extension) as ``(T, N, 3)`` m.

    >>> traj = cordis.read_trajectory("rigid.csv")
    """

def write_trajectory(path: _PathLike, array: _ArrayLike, dt: Optional[float] = None) -> None:
    """Writes positions ``(T, N, 3)`` (any float64-convertible array, m) atomically.

    The format follows the extension (``.csv``, ``.npy``, ``.tra``). ``dt`` (s) is checked;
    none of the formats stores it. A wrong shape raises ValueError, a non-finite value
    TrajectoryError.

    >>> cordis.write_trajectory("rigid.npy", scene.simulate(100))
    """

def example(name: str, unknowns: bool = False, width: float = 25.0, seed: int = 0) -> Scene:
    """The shipped example ``name`` (one of :data:`EXAMPLES`) at its default size.

    With ``unknowns=True`` every positive link-type parameter is unknown, in a box ``width``
    times wide holding the true value at a place drawn from ``seed``.

    >>> truth = cordis.example("rigid")
    >>> scene = cordis.example("rigid", unknowns=True)
    """

@final
class CostReport:
    """Everything a cost says about one parameter vector."""

    @property
    def total(self) -> float:
        """The global cost C = Σ_i c_i (m²; for ``harmonic``, 1 / Σ 1/(e + ε))."""
    @property
    def rmse(self) -> float:
        """sqrt(Σ e / terms): RMS prediction error of a particle, m."""
    @property
    def per_particle(self) -> npt.NDArray[np.float64]:
        """Local cost c_i of every particle ``(N,)`` (0 for fixed particles)."""
    @property
    def terms(self) -> int:
        """Number of (predicted frame, free particle) pairs."""
    @property
    def kind(self) -> str:
        """The cost kind, as text."""

def cost(scene: Scene, traj: _ArrayLike, kind: str = "short") -> CostReport:
    """The cost of ``kind`` of ``scene`` (at its own values) against ``traj`` ``(T, N, 3)`` m.

    The last few compiled (scene, trajectory, kind) triples are cached; an optimiser should use
    :class:`Objective`.

    >>> cordis.cost(truth, truth.simulate(100)).total
    0.0
    """

@final
class Objective:
    """A cost compiled once; ``f(params) -> float`` on vectors laid out as ``param_names()``.

    >>> f = cordis.Objective(truth, traj)
    >>> f(f.param_vector())
    0.0
    """

    def __new__(
        cls,
        scene: Scene,
        traj: _ArrayLike,
        kind: str = "short",
        generation: int = 0,
        precompute: bool = True,
    ) -> "Objective": ...
    def __call__(self, params: _ArrayLike) -> float:
        """The global cost of ``params`` (float64 vector of ``num_params`` values)."""
    def report(self, params: _ArrayLike) -> CostReport:
        """Cost, RMSE, local costs and term count of ``params``."""
    def evaluate_batch(self, params: _ArrayLike) -> npt.NDArray[np.float64]:
        """Costs of every row of ``params`` ``(M, num_params)``, in parallel, GIL released."""
    def param_vector(self) -> npt.NDArray[np.float64]:
        """The scene's own parameter vector."""
    def param_names(self) -> List[str]:
        """``types.NAME.PARAM``, ``particles[i].mass``, ``gravity[k]`` for every slot."""
    @property
    def num_params(self) -> int: ...
    @property
    def frames(self) -> int: ...
    @property
    def particles(self) -> int: ...
    @property
    def terms(self) -> int:
        """Number of (predicted frame, free particle) pairs: rmse = sqrt(cost / terms)."""
    @property
    def kind(self) -> str: ...
    @property
    def linear(self) -> bool:
        """True when the short cost is a precomputed quadratic form (O(θ²) calls)."""

@final
class IdentifyResult:
    """What :func:`identify` found."""

    HISTORY_COLUMNS: List[str]

    @property
    def scene(self) -> Scene:
        """The scene with the identified values written in."""
    @property
    def params(self) -> Dict[str, float]:
        """Identified value of each unknown, by name."""
    @property
    def truth(self) -> Optional[Dict[str, float]]:
        """True value of each unknown when ``truth`` was given."""
    @property
    def cost(self) -> float: ...
    @property
    def rmse(self) -> float:
        """sqrt(cost / terms), m."""
    @property
    def history(self) -> npt.NDArray[np.float64]:
        """One row per generation, columns :attr:`HISTORY_COLUMNS` (NaN error without truth)."""
    @property
    def evals(self) -> int: ...
    @property
    def generations(self) -> int: ...
    @property
    def seconds(self) -> float: ...
    @property
    def strategy(self) -> str: ...
    @property
    def param_error_pct(self) -> Optional[float]:
        """Mean relative error against the truth, %."""
    @property
    def stopped_by(self) -> str:
        """``generations``, ``max_evals``, ``time_limit``, ``target_cost``, ``callback``, ``interrupted``."""

def identify(
    scene: Scene,
    traj: _ArrayLike,
    strategy: str = "auto",
    generations: Optional[int] = 1000,
    population: int = 100,
    seed: int = 0,
    callback: Optional[Callable[[int, float, Dict[str, float]], Optional[bool]]] = None,
    *,
    noise: float = 0.0,
    cost: str = "short",
    time_limit: Optional[float] = None,
    target_cost: Optional[float] = None,
    max_evals: Optional[int] = None,
    threads: Optional[int] = None,
    truth: Optional[Scene] = None,
    checkpoint: Optional[_PathLike] = None,
    resume: Optional[_PathLike] = None,
    dt: Optional[float] = None,
    stable_horizon: Optional[int] = None,
    stable_spread: float = 2.0,
) -> IdentifyResult:
    """Identifies the unknowns of ``scene`` from the observed positions ``traj`` (GIL released).

    ``stable_horizon=H`` rejects (cost ``inf``) every candidate whose stability bound exceeds
    1 or whose free run from the observed frames 0 and 1 diverges within ``H`` frames: a
    non-finite or runaway position, or the free particles' spread about their centroid beyond
    ``stable_spread`` times the largest observed (CLI ``--stable-horizon``).

    ``callback(generation, best_cost, params)`` runs after every generation; returning False
    stops the run, an exception stops it and is raised again. Ctrl-C stops cleanly and raises
    KeyboardInterrupt with the partial result as its ``result`` attribute.

    >>> res = cordis.identify(scene, traj, generations=500, truth=truth)
    >>> res.param_error_pct < 1.0
    True
    """

@final
class DiscoverResult:
    """What :func:`discover` found."""

    @property
    def scene(self) -> Scene:
        """The proposed scene (every value known; initial state from the first frames)."""
    @property
    def links(self) -> List[Dict[str, Any]]:
        """Per link of ``scene``: ``particles``, ``type``, own ``stiffness``/``rest_length``/
        ``damping`` and their ``…_se``, ``score`` (Wald statistic) and ``threshold``."""
    @property
    def near_misses(self) -> List[Dict[str, Any]]:
        """Rejected candidates closest to the threshold: ``particles``, ``score``, ``threshold``."""
    @property
    def radius(self) -> float:
        """Candidate radius, m."""
    @property
    def candidates(self) -> int:
        """Number of candidate pairs."""
    @property
    def cost(self) -> float:
        """Short cost of the proposed scene on the trajectory, m²."""
    @property
    def rmse(self) -> float:
        """RMS one-step prediction error of the proposed scene, m."""
    @property
    def solver(self) -> Dict[str, Any]:
        """The exact solver's report of the catalogue refit."""
    @property
    def notes(self) -> List[str]:
        """How the answer was reached."""

def discover(
    traj: _ArrayLike,
    dt: float,
    total_mass: Optional[float] = None,
    masses: Optional[Sequence[float]] = None,
    max_range: Optional[float] = None,
    noise_level: float = 0.0,
    threshold_scale: float = 1.0,
    type_tolerance: float = 1e-3,
) -> DiscoverResult:
    """Proposes a spring network (links, masses, gravity, types) from positions alone
    (GIL released). Give ``total_mass`` (kg, moving particles) or every particle's ``masses``.

    >>> res = cordis.discover(traj, truth.dt, total_mass=12.3)  # doctest: +SKIP
    """

def random_network(seed: int, masses: int, types: int) -> Scene:
    """A seed-generated random spring network (particle 0 fixed, gravity, random velocities)."""

def _cli_main(argv: List[str], /) -> int:
    """Runs the ``cordis`` command line (``argv[0]`` is the program name)."""
