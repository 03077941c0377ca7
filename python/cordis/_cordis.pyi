"""Type stubs of the compiled extension ``cordis._cordis`` (re-exported by ``cordis``)."""

import os
from typing import (
    Any,
    Callable,
    Dict,
    Iterator,
    List,
    Literal,
    Mapping,
    Optional,
    Sequence,
    Tuple,
    Union,
    final,
    overload,
)

import numpy as np
import numpy.typing as npt

__version__: str
EXAMPLES: Tuple[str, ...]
__all__ = [
    "__version__",
    "PopulationEvaluator",
    "CordisError",
    "SceneError",
    "TrajectoryError",
    "FormatError",
    "DivergedError",
    "CheckpointError",
    "CordisIOError",
    "CostKindError",
    "ParamLengthError",
    "SceneKeyError",
    "SceneIndexError",
    "ArgumentError",
    "RefusedError",
    "RunError",
    "Scene",
    "Unknown",
    "Particle",
    "ParticleList",
    "LinkType",
    "LinkTypes",
    "read_trajectory",
    "write_trajectory",
    "export_mjcf",
    "export_gltf",
    "example",
    "EXAMPLES",
    "CostReport",
    "Objective",
    "cost",
    "IdentifyResult",
    "identify",
    "DiscoverResult",
    "discover",
    "scene_from_markers",
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
    """A file could not be read or written (``errno``, ``strerror``, ``filename`` as OSError
    when the system gave an errno; ``place`` is always the file: an input above the size limit,
    2 GiB or 256 MiB from a stream, has no errno)."""

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

class ArgumentError(CordisError, ValueError):
    """An argument out of its domain (``width=float("nan")``); ``place`` names it."""

    place: str
    message: str

class RefusedError(CordisError, ValueError):
    """The strategy cannot run on this problem (a muscle for an exact solver, free masses
    without ``total_mass``…): refused before any work; ``message`` says what to do instead."""

    place: str
    message: str

class RunError(CordisError, RuntimeError):
    """The run failed: the solver found no estimate, an evaluation failed, or a checkpoint
    could not be written; ``place`` and ``message`` say which."""

    place: str
    message: str

class CheckpointError(CordisError):
    """A checkpoint that reads but does not fit the run it should resume, naming what differs
    (one that cannot be opened or read is a ``CordisIOError``)."""

    place: str
    message: str

class SceneKeyError(SceneError, KeyError):
    """A link-type or parameter name the scene does not have; ``place`` names it.

    >>> scene.types["rib"]["stifness"]   # SceneKeyError: types.rib.stifness: `spring` types
    ...                                  # have no parameter `stifness` (they have: …)
    """

class SceneIndexError(SceneError, IndexError):
    """A particle or type index out of range (``scene.particles[99]``); ``place`` names it."""

@final
class Unknown:
    """A parameter to identify, searched in ``[min, max]``, starting from ``init``.

    Without ``init`` a simulation uses the box's middle (geometric when the box is positive and
    spans more than a decade). Assign it where a number goes:

    >>> scene.types["rib"]["stiffness"] = cordis.Unknown(1.0, 1000.0)
    >>> scene.particles[2].mass = cordis.Unknown(0.1, 10.0, init=1.0)

    Raises ValueError unless ``min <= max`` (finite) and ``init`` is inside the box.
    """

    def __new__(cls, min: float, max: float, init: Optional[float] = None) -> "Unknown": ...
    @property
    def min(self) -> float: ...
    @property
    def max(self) -> float: ...
    @property
    def init(self) -> Optional[float]: ...
    @property
    def value(self) -> float:
        """The value a simulation uses before identification: ``init``, else the middle."""
    def to_dict(self) -> Dict[str, float]:
        """``{"min": …, "max": …}`` (and ``"init"``), as in the JSON format."""
    def __eq__(self, other: object, /) -> bool: ...
    __hash__: None  # type: ignore[assignment]
    def __reduce__(self) -> Tuple[Any, Tuple[float, float, Optional[float]]]: ...

_Param = Union[float, Unknown]
_ParamIn = Union[float, Unknown, Mapping[str, float]]

@final
class Particle:
    """One particle of a scene, a view that writes through (``scene.particles[i]``).

    Every attribute is settable; a value the scene refuses raises SceneError naming it
    (``particles[3].mass: must be a positive number, got 0``) and changes nothing.

    >>> p = scene.particles[3]
    >>> p.mass = 2.0
    >>> p.pos = (0.0, 0.0, 1.5)
    """

    @property
    def index(self) -> int: ...
    @property
    def mass(self) -> _Param:
        """Mass, kg, or ``Unknown`` when it is to be identified."""
    @mass.setter
    def mass(self, value: _ParamIn) -> None: ...
    @property
    def pos(self) -> Tuple[float, float, float]:
        """Initial position x(0), m."""
    @pos.setter
    def pos(self, value: _ArrayLike) -> None: ...
    @property
    def vel(self) -> Tuple[float, float, float]:
        """Initial velocity v(0), m/s."""
    @vel.setter
    def vel(self, value: _ArrayLike) -> None: ...
    @property
    def fixed(self) -> bool:
        """A fixed particle never moves."""
    @fixed.setter
    def fixed(self, value: bool) -> None: ...
    @property
    def group(self) -> Optional[str]:
        """Group name (conditional types pair particles by group), or None."""
    @group.setter
    def group(self, value: Optional[str]) -> None: ...

@final
class ParticleList:
    """``scene.particles``: a sequence of :class:`Particle` views (negative indices work)."""

    def __len__(self) -> int: ...
    def __getitem__(self, i: int, /) -> Particle:
        """Raises SceneIndexError (an IndexError) out of range."""
    def __iter__(self) -> Iterator[Particle]: ...

@final
class LinkType:
    """One entry of the catalogue: a mapping parameter name → value that writes through.

    Keys are the kind's parameters in parameter-vector order (``stiffness``, ``rest_length``,
    ``damping``…; a muscle's ``w_len[k]``, ``w_rate[k]``). Values are floats, or
    :class:`Unknown` for parameters to identify. An assignment is validated: a bad value raises
    SceneError (``types.rib.stiffness: must be a non-negative number, got -1``), an unknown name
    SceneKeyError (a KeyError), and the scene is left unchanged.

    >>> rib = scene.types["rib"]
    >>> rib["stiffness"] = 120.0
    >>> rib["damping"] = cordis.Unknown(0.0, 5.0)
    >>> dict(rib)
    {'stiffness': 120.0, 'rest_length': 1.0, 'damping': Unknown(0.0, 5.0)}
    """

    @property
    def name(self) -> str: ...
    @property
    def kind(self) -> str:
        """``spring``, ``damper``, ``anchor``, ``angle``, ``conditional``, ``muscle``…"""
    @property
    def num_links(self) -> int:
        """Number of listed links of this type."""
    @property
    def max_elongation(self) -> Optional[float]:
        """Provot's critical deformation rate τc (springs only), or None: no limit.

        Settable; ``None`` removes the limit, a value on another kind raises SceneError.
        """
    @max_elongation.setter
    def max_elongation(self, value: Optional[float]) -> None: ...
    def __len__(self) -> int: ...
    def __getitem__(self, key: str, /) -> _Param: ...
    def __setitem__(self, key: str, value: _ParamIn, /) -> None: ...
    def __contains__(self, key: object, /) -> bool: ...
    def __iter__(self) -> Iterator[str]: ...
    def keys(self) -> List[str]: ...
    def values(self) -> List[_Param]: ...
    def items(self) -> List[Tuple[str, _Param]]: ...
    def get(self, key: str, default: Optional[Any] = None) -> Any: ...

@final
class LinkTypes:
    """``scene.types``: the catalogue, a mapping type name → :class:`LinkType` (file order).

    An int index works too (``scene.types[0]``). A missing name raises SceneKeyError.
    """

    def __len__(self) -> int: ...
    def __getitem__(self, key: Union[str, int], /) -> LinkType: ...
    def __contains__(self, name: object, /) -> bool: ...
    def __iter__(self) -> Iterator[str]: ...
    def keys(self) -> List[str]: ...
    def values(self) -> List[LinkType]: ...
    def items(self) -> List[Tuple[str, LinkType]]: ...
    def get(self, name: str, default: Optional[Any] = None) -> Any: ...

@final
class Scene:
    """A Cordis-Anima network (particles, link catalogue, links) with its time step.

    Read one with :meth:`from_json` or :meth:`from_dict`, run it with :meth:`simulate`. Edit it
    in place; every edit is validated (a refused value raises SceneError naming the place and
    leaves the scene unchanged), and :meth:`to_json` writes the edits:

    >>> scene = cordis.example("rigid")
    >>> scene.dt = 0.005
    >>> scene.gravity = (0.0, 0.0, -9.81)
    >>> scene.types["brace"]["stiffness"] = 120.0
    >>> scene.types["brace"]["damping"] = cordis.Unknown(0.0, 2.0)
    >>> scene.particles[3].mass = 2.0
    >>> scene.masses = 1.5 * scene.masses          # whole arrays: masses, positions, velocities
    >>> print(scene)                               # a readable summary

    Equal scenes compare equal; scenes pickle as their JSON text; ``copy.copy`` and
    :meth:`copy` give an independent scene.
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
        """The scene as pretty-printed JSON text (``cordis-scene/1``), edits included."""
    def to_dict(self) -> Dict[str, Any]:
        """The scene as a dict of plain Python values (the JSON format's structure)."""
    def simulate(self, frames: int) -> npt.NDArray[np.float64]:
        """Positions for ``frames`` frames, a C-contiguous float64 array ``(frames, N, 3)`` in m.

        Frame 0 is the initial positions. The GIL is released while it runs (an edit made
        meanwhile by another thread does not affect it). Raises ValueError for a negative
        count, MemoryError for one that cannot be allocated and DivergedError when the motion
        leaves the finite numbers.
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
        """Time step, s. Settable (a positive number, else SceneError)."""
    @dt.setter
    def dt(self, value: float) -> None: ...
    @property
    def gravity(self) -> Tuple[float, float, float]:
        """Acceleration of every free particle, m/s². Settable from 3 finite numbers."""
    @gravity.setter
    def gravity(self, value: _ArrayLike) -> None: ...
    @property
    def particles(self) -> ParticleList:
        """The particles, views that write through: ``scene.particles[3].mass = 2.0``."""
    @property
    def types(self) -> LinkTypes:
        """The catalogue: ``scene.types["rib"]["stiffness"] = 120.0``."""
    @property
    def masses(self) -> npt.NDArray[np.float64]:
        """Masses ``(N,)`` kg, a read-only copy (unknown masses at their starting value).

        Assign a whole ``(N,)`` array to change them (all become known); a wrong shape raises
        ValueError, a non-positive mass SceneError.
        """
    @masses.setter
    def masses(self, value: _ArrayLike) -> None: ...
    @property
    def positions(self) -> npt.NDArray[np.float64]:
        """Initial positions x(0) ``(N, 3)`` m, a read-only copy; assign ``(N, 3)`` to set."""
    @positions.setter
    def positions(self, value: _ArrayLike) -> None: ...
    @property
    def velocities(self) -> npt.NDArray[np.float64]:
        """Initial velocities v(0) ``(N, 3)`` m/s, a read-only copy; assign ``(N, 3)`` to set."""
    @velocities.setter
    def velocities(self, value: _ArrayLike) -> None: ...
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
    def with_unknowns(self, width: float = 4.0) -> "Scene":
        """A copy whose positive known link-type parameters are unknown, in boxes ``width``
        times wide (max/min) centred geometrically on their values (their start).

        Zeros (an absent damping) stay known, as do a muscle's weights, gain and threshold and
        a TGR's tendon. ``width`` must exceed 1 (ArgumentError).

        >>> guess = cordis.example("rigid").with_unknowns(width=4.0)
        """
    def from_frame(self, k: int) -> "Scene":
        """A copy on the clock of a take cropped to start at this scene's frame ``k``.

        Every signal's phase is advanced by ``k dt / period`` (the dt of the world whose TGRs
        read it), so the TGRs are driven by the same commands at the take's frames; the
        tendons' start is the TGR types' ``tendon_position`` / ``tendon_velocity`` (scene
        file keys). SceneError, naming the signal, when TGRs in worlds of different time
        steps read one signal.

        >>> take_scene = cordis.example("tadpole").from_frame(150)
        """
    def copy(self) -> "Scene":
        """An independent copy (edits to one do not change the other)."""
    def __eq__(self, other: object, /) -> bool: ...
    __hash__: None  # type: ignore[assignment]
    def __copy__(self) -> "Scene": ...
    def __deepcopy__(self, memo: Optional[Dict[int, Any]]) -> "Scene": ...
    def __reduce__(self) -> Tuple[Any, Tuple[str]]: ...

@overload
def read_trajectory(
    path: _PathLike,
    /,
    *,
    columns: Optional[str] = None,
    units: Optional[str] = None,
    delimiter: Optional[str] = None,
    with_dt: Literal[False] = False,
) -> npt.NDArray[np.float64]:
    """Reads a trajectory or marker file by extension as ``(T, N, 3)`` m, NaN where missing;
    frames counted from the file's first (a take cropped to frames 100–199 gives T = 100).

    cordis' ``.csv``, ``.npy``, ``.tra``; motion capture ``.c3d``, OpenSim ``.trc``; tracker
    ``.npz`` (TAP-Vid ``tracks (N, T, 2|3)`` + ``visibility (N, T)``, CoTracker); ``.csv`` /
    ``.tsv`` tables with named columns (``columns="frame=Frame,particle=Marker,x=X,y=Y,z=Z"``,
    ``"time=t"``, wide ``"time=Time,x=*_X"``). ``units`` (m, cm, mm) are those of a file that
    does not state them. With ``with_dt=True``: ``(array, dt)``, ``dt`` in s from the file's
    rate, or None.

    >>> traj = cordis.read_trajectory("rigid.csv")
    >>> markers, dt = cordis.read_trajectory("walk.trc", with_dt=True)
    """
@overload
def read_trajectory(
    path: _PathLike,
    /,
    *,
    columns: Optional[str] = None,
    units: Optional[str] = None,
    delimiter: Optional[str] = None,
    with_dt: Literal[True],
) -> Tuple[npt.NDArray[np.float64], Optional[float]]: ...

def export_mjcf(scene: Scene, path: _PathLike) -> None:
    """Writes MuJoCo's MJCF model of ``scene`` atomically (``cordis export --mjcf``): body
    ``p{i}`` per particle on slide joints, tendons, semi-implicit Euler equal to the CORDIS
    step. Angle, conditional and plane links, ``damping_quadratic`` and ``max_elongation``
    have no MJCF element: their data go into ``<custom>`` and :func:`cordis.mujoco.load`
    applies them while MuJoCo integrates. Muscles, TGRs, transmitters, nonlinear drags,
    signals, worlds and unknown parameters raise SceneError naming them.

    >>> cordis.export_mjcf(cordis.example("rigid"), "rigid.xml")
    """

def export_gltf(
    scene: Scene, trajectory: _ArrayLike, path: _PathLike, dt: Optional[float] = None
) -> None:
    """Writes a self-contained glTF 2.0 animation of ``trajectory`` ``(T, N, 3)``, a motion of
    ``scene`` (points and links, one morph target per frame, frames ``dt`` s apart, default
    the scene's), atomically (``cordis export --gltf``).

    >>> cordis.export_gltf(scene, scene.simulate(200), "motion.gltf")
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

    ``kind="static"`` reads every frame as an equilibrium pose (T ≥ 1): 0 exactly when the
    scene is at rest in every frame.

    The last few compiled (scene, trajectory, kind) triples are cached; an optimiser should use
    :class:`Objective`.

    >>> cordis.cost(truth, truth.simulate(100)).total
    0.0
    """

@final
class PopulationEvaluator:
    """A problem compiled once that evaluates populations of genomes (internal coordinates):
    what an executor's remote worker holds (one per Ray actor).

    >>> ev = cordis.PopulationEvaluator(scene, traj, "short", threads=1)
    >>> costs = ev.evaluate(genomes, generation=0)            # (M,) for genomes (M, ev.dim)
    """

    def __new__(
        cls, scene: Scene, traj: _ArrayLike, cost: str = "short", threads: int = 1
    ) -> "PopulationEvaluator": ...
    @property
    def dim(self) -> int:
        """Number of unknowns (length of a genome)."""
    @property
    def num_particles(self) -> int:
        """Number of particles (length of a row of local costs)."""
    def evaluate(
        self, genomes: _ArrayLike, generation: int = 0, local: bool = False
    ) -> Any:
        """Costs ``(M,)`` of genomes ``(M, dim)``; with ``local=True``, ``(costs, local (M, N))``."""

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
        """Number of (predicted frame, free particle) pairs (``static``: (frame, free
        particle)): rmse = sqrt(cost / terms)."""
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
        """The scene with the identified values written in (with take 0's estimated initial
        state when the strategy estimates one)."""
    @property
    def scenes(self) -> List[Scene]:
        """One identified scene per take, each with that take's estimated initial state:
        ``scenes[k].simulate(T)`` replays take k (``scenes[0]`` is ``scene``); ``[scene]``
        when the strategy estimates no initial state."""
    @property
    def params(self) -> Dict[str, float]:
        """Identified value of each unknown, by name."""
    @property
    def truth(self) -> Optional[Dict[str, float]]:
        """True value of each unknown when ``truth`` was given."""
    @property
    def cost(self) -> float:
        """The cost the strategy minimised at its estimate, m²: the chosen cost kind's, or for
        ``output-error`` the replay's weighted squared position residuals over the takes."""
    @property
    def rmse(self) -> float:
        """sqrt(cost / terms), m (``output-error``: per observed coordinate)."""
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
        """``converged`` (the solver's own criterion met), ``strategy_budget`` (its restarts or
        cycles spent short of it), ``not_determined`` (unknowns the data leave free), or a stop
        rule: ``generations``, ``max_evals``, ``time_limit``, ``target_cost``, ``callback``,
        ``interrupted``."""
    @property
    def report(self) -> Optional[Dict[str, Any]]:
        """The solver's own report (as the CLI's ``"solver"``); None for evolution strategies."""
    @property
    def warnings(self) -> List[str]:
        """What the CLI prints as ``warning:`` lines (also raised with ``warnings.warn``)."""
    @property
    def stderr(self) -> Optional[Dict[str, float]]:
        """Standard error of each unknown (its own unit; inf: not determined), by name, for
        ``output-error``; None for strategies that do not estimate it. An unknown whose
        standard error was not computed (a matrix-free solve that did not settle) is absent;
        ``report["stderr_at_least"]`` names it with a lower bound."""
    @property
    def intervals(self) -> Optional[Dict[str, Tuple[float, float]]]:
        """95 % interval ``(low, high)`` of each unknown, by name; None when not estimated (an
        unknown whose standard error was not computed is absent, as in ``stderr``).

        ``value ± 1.96 stderr``, or on ``ln value`` (``value * exp(±1.96 stderr / value)``)
        for a positive unknown searched in log coordinates (a box wider than a factor 10:
        usually stiffness, rest length, damping, mass): never below zero. An unknown the data
        do not determine (``stderr`` inf) has its box ``(min, max)``, finite: the data do not
        narrow it (docs/identification.md, Uncertainty)."""
    @property
    def covariance(self) -> Optional[npt.NDArray[np.float64]]:
        """Covariance of the unknowns in ``list(params)`` order, ``(n, n)``; inf on the diagonal
        of an undetermined unknown (0 beside it); None when not estimated or when some standard
        error was not computed."""
    @property
    def sigma(self) -> Optional[float]:
        """Noise of the observed positions estimated from the residuals, m; None when not
        estimated: another strategy, or a fit the run stopped before it reached the whole take
        (``report["end"] == "stopped"``; ``report["sigma"]``, the CLI's ``solver.sigma``, is
        then the residuals' level at the best point so far, not an estimate). With
        ``weights``, the noise of a weight-1 coordinate (a coordinate of weight w is read as
        noise ``sigma / w``)."""
    def write_report(
        self,
        path: _PathLike,
        trajectory: _ArrayLike,
        visible: Optional[_ArrayLike] = None,
        title: Optional[str] = None,
        markers: Optional[Sequence[int]] = None,
        weights: Optional[_ArrayLike] = None,
    ) -> None:
        """Writes the identification report (``cordis report``): one self-contained HTML page
        on :attr:`scene` and the observed ``trajectory`` ``(T, N, 3)`` (NaN, or ``visible``
        False, where missing) — data summary, parameters with this run's intervals, per-marker
        observed vs model, residuals, convergence, the 3-D replay; light and dark themes.
        Written atomically. (``report`` is the solver's report, hence the name.) ``markers``
        and ``weights`` as given to :func:`identify` (default: this run's own; for a
        scene-ordered array after a run with markers, ``markers=list(range(N))``): marker m is the scene's particle
        ``markers[m]`` (``trajectory`` then holds the markers, ``(T, M, 3)``); the weights add
        the weighted position RMS to the fit.

        >>> res = cordis.identify(scene, traj, strategy="output-error")
        >>> res.write_report("report.html", traj)
        """

def identify(
    scene: Scene,
    traj: Union[_ArrayLike, Sequence[_ArrayLike]],
    strategy: str = "auto",
    generations: Optional[int] = 1000,
    population: Optional[int] = None,
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
    executor: Optional[Any] = None,
    islands: Optional[int] = None,
    migrate_every: int = 10,
    migrants: int = 2,
    total_mass: Optional[float] = None,
    lock: Optional[Union[str, _PathLike, Sequence[str]]] = None,
    param_gene: Optional[_PathLike] = None,
    descent_start: Optional[int] = None,
    descent_every: Optional[int] = None,
    crossover: Optional[str] = None,
    local_cost: Optional[str] = None,
    restarts: Optional[str] = None,
    plus: bool = False,
    correlated: bool = False,
    visible: Optional[Union[_ArrayLike, Sequence[Optional[_ArrayLike]]]] = None,
    markers: Optional[Sequence[int]] = None,
    weights: Optional[_ArrayLike] = None,
    loss: str = "squared",
    intervals: str = "wald",
) -> IdentifyResult:
    """Identifies the unknowns of ``scene`` from the observed positions ``traj`` (GIL released).

    Tracked motion: ``traj`` may hold NaN (a missing coordinate), have fewer particles than
    the scene (the rest are hidden, simulated), or be a list of arrays (several takes of the
    same object: one parameter set, each take its own initial state); ``visible`` (boolean
    ``(T, N)``, or a list of one per take, None for a take whose particles are all visible)
    hides a particle where it is False; ``markers[j]`` is the scene particle the data's
    particle j tracks (the rest hidden; fixed particles need not be tracked); ``weights``:
    each marker's weight, 1/σ relative: shape ``(M,)`` one per marker, or ``(M, 3)`` (or a
    flat ``3M``) one per marker and coordinate x, y, z (read by ``output-error`` only); ``loss``: ``"squared"``, or ``"huber"``/``"cauchy"``,
    robust against tracking outliers and swapped markers (output-error); ``intervals``:
    ``"wald"`` (from the standard errors, checked along each unknown's profile direction and
    widened where the cost is flatter there than its quadratic model) or ``"profile"`` (the
    profile likelihood's where it is flatter: every other variable refitted at each edge,
    several times the fit's time; output-error). Only ``output-error``
    reads gaps and takes, and ``auto`` picks it for them and for noisy data; its result has
    ``stderr``, ``intervals``, ``covariance`` and ``sigma``, and its ``scene`` carries the
    estimated initial state (``res.scene.simulate(T)`` replays the take).

    What ``cordis identify`` does, under the same option names (``time_limit`` is
    ``--time-limit``), through the same session: the same checks, the same result.
    ``total_mass`` (kg) is needed when the free particles' masses are unknown; ``lock`` keeps
    unknowns at their start (a ``NAME.lock`` file or names); ``param_gene`` reads a thesis
    ``Param.gene`` file (its ``damping`` only as 0); ``descent_start``/``descent_every`` set
    the thesis ES's Powell descent (None: 400 and 100) and ``crossover`` its crossover
    (``"mean"``: Annexe 1, the default; ``"n-parent"``, ``"mn-parent"``: §3.2), refused with a
    strategy other than ``thesis``/``t2m``, as are ``local_cost`` (``"positions"``, the
    default, or ``"distances"``: eq 3.3 as printed, the error of the predicted distances to
    linked particles; short cost, no executor) and ``param_gene``'s ``pcross``, ``pmut`` and
    ``reducer``; ``restarts`` gives ``cmaes`` ``"ipop"`` (the default) or ``"bipop"``
    restarts (Hansen 2009; refused with another strategy); ``plus`` and ``correlated`` give ``self-adaptive``
    (μ+λ) selection and correlated mutations (refused with another strategy). ``threads`` beyond the machine's cores are capped, with a warning.

    A strategy that cannot run on the problem is refused before any work (``RefusedError``, a
    ValueError naming why), an option out of range raises ``ArgumentError`` (a ValueError), a
    run that finds no estimate ``RunError`` (a RuntimeError), a checkpoint of another request
    ``CheckpointError`` naming what differs — all ``CordisError``; what the CLI prints as
    ``warning:`` is raised with ``warnings.warn`` and kept in ``IdentifyResult.warnings``.

    ``executor``: None/``"local"``, ``"ray"`` or an executor object (``cordis.RayExecutor``):
    where populations are evaluated; the result is the same on every executor. ``islands``:
    that many thesis populations exchanging their ``migrants`` best every ``migrate_every``
    generations (deterministic given the seed and the island count).

    ``strategy``: ``"auto"``, ``"thesis"`` (the ES of thesis §3.2 and Annexe 1 as written),
    ``"t2m"`` (the same ES with freer operators), ``"least-squares"``, ``"hybrid"``, ``"cmaes"``,
    ``"self-adaptive"``, ``"annealing"``, ``"parisian"``, ``"output-error"`` (the
    maximum-likelihood fit of simulated to observed positions) or ``"levenberg-marquardt"``
    (nonlinear least squares on the short cost's residuals; ``cost="short"`` or
    ``cost="static"`` only, residuals computed in this process even with an ``executor``;
    ``population`` is ignored).

    ``cost``: ``"short"``, ``"horizon:H"``, ``"long"``, ``"progressive[:G[:START]]"``,
    ``"harmonic[:EPS]"`` or ``"static"``: every frame of ``traj`` is a pose at rest (one frame
    is enough) and its residual is the net force at zero velocity, as the step from rest
    ``dt² (F/m + g)`` (m); it determines stiffnesses and rest lengths, not masses and
    stiffnesses together (only K/m), and refuses unknown dampings, drags and friction by name
    (``RefusedError``); ``auto`` then runs ``levenberg-marquardt``.

    ``stable_horizon=H`` rejects (cost ``inf``) every candidate whose stability bound exceeds
    1 or whose free run from the observed frames 0 and 1 diverges within ``H`` frames: a
    non-finite or runaway position, or the free particles' spread about their centroid beyond
    ``stable_spread`` times the largest observed (CLI ``--stable-horizon``).

    ``callback(generation, best_cost, params)`` runs after every generation; returning False
    stops the run, an exception stops it and is raised again. Ctrl-C stops cleanly and raises
    KeyboardInterrupt with the partial result as its ``result`` attribute. A ``checkpoint``
    that cannot be written (a full disk) raises RunError naming the file once the run is
    over, with the whole result as its ``result`` attribute.

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
        """Per link of ``scene``: ``particles``, ``kind`` (``spring``, ``anchor``, ``damper``),
        ``type``, own ``stiffness``/``rest_length``/
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
    @property
    def noise_level(self) -> float:
        """The position noise used, m: given, or estimated when ``noise_estimated``."""
    @property
    def noise_estimated(self) -> bool:
        """Whether ``noise_level`` was estimated from the data (no ``noise_level`` given)."""
    @property
    def undetermined(self) -> List[Dict[str, Any]]:
        """What the data cannot decide, by name: ``what`` (``masses``…), ``particles``,
        ``links``, ``why`` (each also raised with ``warnings.warn``)."""
    @property
    def identified(self) -> Optional[Scene]:
        """With ``identify=True``: the identified scene (every value known, the estimated
        initial state); else None."""
    @property
    def identification(self) -> Optional[Dict[str, Any]]:
        """With ``identify=True``: ``params`` (each unknown's ``name``, ``discovered``,
        ``value``, ``stderr``, ``low``, ``high``, ``at_bound``), ``end`` and ``converged`` (the estimator's
        own status), ``sigma``, ``noise_level``, ``undetermined``, ``gravity_fitted``,
        ``reference``, as ``cordis discover --identify``'s summary; else None."""
    @property
    def link_test(self) -> Optional[Dict[str, Any]]:
        """With ``link_test=True``: whether it decided the graph (``applied``: False, with a
        warning, when its fit stayed above the noise), the output-error link test's fit (``end``, ``converged``,
        ``sigma``, ``noise_level``, ``variables``, ``iterations``), ``kept``, and every
        candidate pair's verdict (``pairs``: ``particles``, ``kind``, estimates and standard
        errors, ``score``, ``threshold``, ``kept``); else None."""

def scene_from_markers(
    markers: _ArrayLike,
    dt: float,
    total_mass: float,
    *,
    neighbours: Optional[int] = None,
    radius: Optional[float] = None,
    types: str = "family",
    width: float = 4.0,
    gravity: Optional[Tuple[float, float, float]] = None,
    still: Optional[float] = None,
    family_tolerance: float = 0.05,
) -> Scene:
    """A spring network on tracked markers ``(T, N, 3)`` (NaN where missing), every parameter
    unknown in a box, ready for :func:`identify` (as ``cordis scene from-markers``).

    One particle per marker at its first observed position, fixed when it never moves (within
    ``still`` m of its median; default 2 % of the markers' extent; then at the mean of its
    observations), masses ``total_mass / N``;
    springs to the ``neighbours`` nearest markers (default 6) or between every pair closer
    than ``radius`` m; one type per family of equal first-frame lengths (``types="family"``)
    or per link (``"link"``); rest lengths in boxes ``width`` times wide around them, stiffness
    and damping under the shared stability bound; ``gravity`` (m/s²) defaults to
    ``(0, -9.81, 0)`` (y up).

    >>> markers, dt = cordis.read_trajectory("markers.csv", with_dt=True)
    >>> scene = cordis.scene_from_markers(markers, 0.01, 0.54, radius=0.18)
    """

def discover(
    traj: _ArrayLike,
    dt: float,
    total_mass: Optional[float] = None,
    masses: Optional[Sequence[float]] = None,
    max_range: Optional[float] = None,
    noise_level: Optional[float] = None,
    threshold_scale: float = 1.0,
    type_tolerance: float = 1e-3,
    gravity: Optional[Tuple[float, float, float]] = None,
    kinds: Optional[Sequence[str]] = None,
    identify: bool = False,
    link_test: bool = False,
) -> DiscoverResult:
    """Proposes a network of springs, anchors and dampers (links with their ``kind``, masses,
    gravity, types) from positions alone (GIL released). Give ``total_mass`` (kg, moving
    particles) or every particle's ``masses``. ``kinds``: the link kinds looked for, of
    ``"spring"``, ``"anchor"`` (to a fixed particle), ``"damper"`` (isotropic); default all three; an
    unknown name raises ``ValueError``. ``identify=True`` then fits the discovered network by
    output-error on the same motion (``res.identified``, ``res.identification``; refused with
    ``CordisError`` when the discovery names something as not determined; Ctrl-C during the
    fit raises ``KeyboardInterrupt`` whose ``result`` is the discovery without it). ``link_test=True``
    first tests every candidate pair again by output error (each pair a spring of its own,
    kept when its stiffness stands clear of 0 against its standard error; slower, more
    powerful under noise): the graph is then the test's, its fit in ``res.link_test``.

    >>> res = cordis.discover(traj, truth.dt, total_mass=12.3)  # doctest: +SKIP
    """

def random_network(seed: int, masses: int, types: int) -> Scene:
    """A seed-generated random spring network (particle 0 fixed, gravity, random velocities)."""

def _cli_main(argv: List[str], /) -> int:
    """Runs the ``cordis`` command line (``argv[0]`` is the program name)."""
