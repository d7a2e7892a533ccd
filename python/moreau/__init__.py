"""moreau: 2D granular contact dynamics (nonsmooth contact dynamics, Moreau–Jean).

Solve one frictional contact problem ``u = W r + q`` (Signorini and Coulomb per contact)::

    import moreau
    problem = moreau.read_fc2d("problem.dat")          # or moreau.Problem(W, q, mu)
    result = moreau.solve(problem, solver="nlgs", tol=1e-8)
    result.r, result.u, result.converged, result.error

or step a granular simulation::

    sim = moreau.Simulation.from_scene("scenes/pile.toml")
    for _ in range(100):
        report = sim.step()
    sim.positions, sim.velocities, sim.contacts()

Arrays are numpy arrays (copies). Errors raise :class:`MoreauError` with the command line's
message; what the command line prints as a warning (a scene's, a start's) is issued once as a
``UserWarning``. Solves and steps release the GIL.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import os
from os import PathLike
import warnings
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _moreau
from ._moreau import MoreauError, World, __version__

__all__ = [
    "MoreauError",
    "Problem",
    "SolveResult",
    "Simulation",
    "World",
    "deposit",
    "read_fc2d",
    "solve",
    "__version__",
]

SOLVERS = ("nlgs", "cpg", "pcpg", "latin", "jacobi", "apgd", "newton", "nlgs-newton", "interior-point")
#: What judges convergence: the relative natural-map error, LMGC90's tests, or every contact's
#: residual in velocity units against the largest free velocity or, for ``step-velocity``, one
#: step of the applied acceleration (g h) (for simulation steps).
CRITERIA = ("natural", "quad", "maxm", "qm16", "velocity", "step-velocity")
#: NLGS's contact orders; ``colours`` and ``worklist`` need a matrix-free problem (a step's).
ORDERINGS = ("forward", "backward", "symmetric", "shuffled", "colours", "worklist")

Path = Union[str, "PathLike[str]"]


def _f64(a: Any, name: str) -> bytes:
    try:
        arr = np.ascontiguousarray(a, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise MoreauError(f"{name}: not an array of numbers ({e})") from None
    if arr.ndim != 1:
        raise MoreauError(f"{name}: expected a 1-D array, got shape {arr.shape}")
    return arr.astype("<f8", copy=False).tobytes()


def _count(x: Any, name: str) -> int:
    """``x`` as a count (a whole number >= 0), or a MoreauError naming it."""
    try:
        whole = not isinstance(x, bool) and int(x) == x and x >= 0
    except (TypeError, ValueError):
        whole = False
    if not whole:
        raise MoreauError(f"{name} {x}: must be a whole number >= 0")
    return int(x)


def _from(b: bytes, dtype: str, columns: int = 1) -> np.ndarray:
    a = np.frombuffer(b, dtype=dtype).copy()
    return a.reshape(-1, columns) if columns > 1 else a


class Problem:
    """One step's frictional contact problem ``u = W r + q`` with friction ``mu`` per contact.

    ``W`` is 2n × 2n (a scipy.sparse matrix or a dense array), ``q`` has 2n entries and ``mu``
    n; vectors interleave per contact, normal first: ``(r_n0, r_t0, r_n1, r_t1, …)``.
    """

    def __init__(self, W: Any, q: Any, mu: Any) -> None:
        if isinstance(W, _moreau.Problem):
            self._inner = W
            return
        indptr, indices, data, shape = _csr(W)
        mu_bytes = _f64(mu, "mu")
        n = len(mu_bytes) // 8
        if shape != (2 * n, 2 * n):
            raise MoreauError(f"W has shape {shape}, expected {(2 * n, 2 * n)} (2 rows per contact, {n} contacts from mu)")
        self._inner = _moreau.Problem.from_csr(n, indptr, indices, data, _f64(q, "q"), mu_bytes)

    @property
    def n_contacts(self) -> int:
        return self._inner.n_contacts

    @property
    def q(self) -> np.ndarray:
        return _from(self._inner.q, "<f8")

    @property
    def mu(self) -> np.ndarray:
        return _from(self._inner.mu, "<f8")

    @property
    def matrix_free(self) -> bool:
        """Whether W is ``B M⁻¹ Bᵀ`` of a simulation step, never assembled."""
        return self._inner.matrix_free

    def velocity(self, r: Any) -> np.ndarray:
        """``u = W r + q``."""
        return _from(self._inner.velocity(_f64(r, "r")), "<f8")

    def write_fc2d(self, path: Path, sparse: bool = True) -> None:
        """Writes a Siconos fc2d file (17 significant digits)."""
        self._inner.write_fc2d(path, sparse)

    def __repr__(self) -> str:
        kind = "matrix-free" if self.matrix_free else "explicit"
        return f"moreau.Problem({self.n_contacts} contacts, {kind} W)"


def _csr(W: Any) -> Tuple[bytes, bytes, bytes, Tuple[int, int]]:
    """W as CSR bytes (int64 indptr and indices, float64 data) and its shape."""
    if hasattr(W, "tocsr"):
        csr = W.tocsr()
        csr.sum_duplicates()
        shape = tuple(int(s) for s in csr.shape)
        return (
            np.asarray(csr.indptr, dtype="<i8").tobytes(),
            np.asarray(csr.indices, dtype="<i8").tobytes(),
            np.asarray(csr.data, dtype="<f8").tobytes(),
            shape,  # type: ignore[return-value]
        )
    dense = np.asarray(W, dtype=np.float64)
    if dense.ndim != 2:
        raise MoreauError(f"W: expected a matrix, got shape {dense.shape}")
    rows, cols = np.nonzero(dense)
    indptr = np.zeros(dense.shape[0] + 1, dtype="<i8")
    np.add.at(indptr, rows + 1, 1)
    return (
        np.cumsum(indptr).astype("<i8").tobytes(),
        cols.astype("<i8").tobytes(),
        dense[rows, cols].astype("<f8").tobytes(),
        (int(dense.shape[0]), int(dense.shape[1])),
    )


def read_fc2d(path: Path) -> Problem:
    """Reads a Siconos fc2d problem file (dense or sparse W)."""
    return Problem(_moreau.read_fc2d(path), None, None)


def deposit(disks: int, mu: float = 0.3, seed: int = 7) -> Problem:
    """The first step of ``disks`` disks (radius 2-3 mm) deposited in a 20 cm box and loaded by
    gravity from rest, every pair at friction ``mu`` (``moreau generate deposit``; 2,000 disks at
    the defaults are scenes/deposit_2k.toml's first step): the frictional deposit, hard for every
    solver when ``mu > 0``."""
    return Problem(_moreau.deposit(disks, mu, seed), None, None)


@dataclass
class SolveResult:
    """What a solve returns; ``error`` is the f64 natural-map error of ``r``, ``judged_error``
    the measure its criterion judged against ``tol`` (``error`` itself under ``natural``)."""

    r: np.ndarray
    u: np.ndarray
    converged: bool
    error: float
    judged_error: float
    #: The answer's worst contact residual in velocity units over the largest free velocity (the
    #: velocity test's measure, whatever the criterion): what ``error`` hides where heavy grains'
    #: impulses set the natural map's scale.
    velocity_error: float
    iterations: int
    seconds: float
    w_products: int
    #: Why the solve stopped, by name: converged, max_iter, stalled, diverged, breakdown or
    #: unbounded (impulses that grew without stopping the contacts they load).
    stop: str
    stop_reason: str
    solver: str
    device: str
    #: (iteration, seconds, error) at each point the error was measured.
    history: List[Tuple[int, float, float]] = field(default_factory=list)
    #: A solve split across devices, part by part: (device, iterations, seconds, error) — on a
    #: GPU, f32 sweeps (mixed ones that stalled, then plain ones) and an f64 finish on the CPU.
    #: Empty when one device did it all.
    parts: List[Tuple[str, int, float, float]] = field(default_factory=list)
    #: Iterations run on a GPU.
    gpu_iterations: int = 0
    #: What the solver chose on its own (LATIN's search direction, the focus's share, a skipped
    #: acceleration), a line each.
    notes: List[str] = field(default_factory=list)


def solve(
    problem: Problem,
    solver: str = "nlgs",
    tol: float = 1e-8,
    max_iter: int = 10_000,
    device: str = "cpu",
    threads: int = 0,
    r0: Optional[Any] = None,
    history_every: int = 0,
    anderson: int = 0,
    focus: int = 0,
    criterion: str = "natural",
    ordering: str = "forward",
    omega: float = 1.0,
) -> SolveResult:
    """Solves ``problem`` with ``solver`` (one of :data:`SOLVERS`) to ``tol`` on ``criterion``
    (one of :data:`CRITERIA`; the relative natural-map error by default), on ``device``
    (``cpu``, ``gpu`` or ``auto``) with ``threads`` CPU threads (0: all cores), from ``r0``
    (zero if None). NLGS sweeps in ``ordering`` (one of :data:`ORDERINGS`), mixes its last
    ``anderson`` sweeps (Anderson acceleration, 0: off) and, on a matrix-free problem (a
    simulation step's), follows each full sweep with ``focus`` sweeps over the contacts around
    its largest changes (0: off; iterations then count sweeps' worth of contact updates), and
    relaxes each contact's update by ``omega`` in (0, 2) (1: plain Gauss–Seidel; above 1 each
    update is projected back onto the cone). Not converging is not an error: the result says so."""
    if not isinstance(problem, Problem):
        raise MoreauError(f"problem: expected a moreau.Problem, got {type(problem).__name__}")
    if isinstance(max_iter, bool) or int(max_iter) != max_iter or max_iter < 0:
        raise MoreauError(f"max_iter {max_iter}: must be a whole number >= 1")
    anderson = _count(anderson, "anderson")
    focus = _count(focus, "focus")
    r0_bytes = None if r0 is None else _f64(r0, "r0")
    d = _moreau.solve(problem._inner, solver, float(tol), int(max_iter), device, int(threads), r0_bytes,
                      int(history_every), anderson, focus, criterion, ordering, float(omega))
    d["r"] = _from(d["r"], "<f8")
    d["u"] = _from(d["u"], "<f8")
    return SolveResult(**d)


class Simulation:
    """A granular world advanced one Moreau–Jean step at a time.

    Build one from a scene file (:meth:`from_scene`) or from a :class:`World`::

        world = moreau.World([("glass", 2500.0)], friction=0.3, gravity=(0.0, -9.81))
        world.add_wall((-1.0, 0.0), (1.0, 0.0), "glass")
        world.add_disk((0.0, 0.05), 0.05, "glass")
        sim = moreau.Simulation(world, h=1e-3)
    """

    def __init__(self, world: World, h: float, theta: float = 0.5, alert: Optional[float] = None,
                 solver: str = "nlgs", tol: float = 1e-4, max_iter: int = 10_000, anderson: int = 0,
                 focus: int = 0, criterion: str = "natural", ordering: str = "forward",
                 projection_slack: Optional[float] = None, omega: float = 1.0) -> None:
        self._checked = False
        if isinstance(world, _moreau.Simulation):
            self._inner = world
            return
        self._inner = _moreau.Simulation(world, h, theta, alert, solver, tol, max_iter,
                                         _count(anderson, "anderson"), _count(focus, "focus"), criterion, ordering,
                                         projection_slack, float(omega))

    def set_solver(self, solver: Optional[str] = None, tol: Optional[float] = None,
                   max_iter: Optional[int] = None, criterion: Optional[str] = None,
                   ordering: Optional[str] = None, anderson: Optional[int] = None,
                   focus: Optional[int] = None, omega: Optional[float] = None,
                   block_sweeps: Optional[int] = None) -> None:
        """Sets the solver of the following steps, as ``moreau run``'s options override a
        scene's: each argument given replaces the current setting, the others stay. Settings
        that cannot run (``max_iter`` 0, a solver the device or the rolling rows refuse) raise
        MoreauError and change nothing. ``block_sweeps`` > 0: the GPU's NLGS sweeps blocks of
        contacts that many times a dispatch (``--block-sweeps``)."""
        def count(x: Optional[int], name: str) -> Optional[int]:
            return None if x is None else _count(x, name)
        self._inner.set_solver(solver, None if tol is None else float(tol), count(max_iter, "max_iter"),
                               criterion, ordering, count(anderson, "anderson"), count(focus, "focus"),
                               None if omega is None else float(omega), count(block_sweeps, "block_sweeps"))

    def set_time_step(self, h: float) -> None:
        """Sets the time step (s) of the following steps, as ``moreau run --time-step`` does; the
        next step starts from the last step's impulses scaled to it. A step that is not finite
        and positive raises MoreauError and changes nothing."""
        self._inner.set_time_step(float(h))

    @property
    def time_step(self) -> float:
        """The time step (s) of the steps."""
        return self._inner.time_step

    def solver_settings(self) -> Dict[str, Any]:
        """The solver of the steps and its options: ``solver``, ``tol``, ``max_iter``,
        ``criterion``, ``ordering``, ``anderson``, ``focus``, …"""
        return self._inner.solver_settings()

    @classmethod
    def from_scene(cls, path: Path) -> "Simulation":
        """The simulation a scene file describes (bodies, walls, materials, effects, settings)."""
        return cls(_moreau.Simulation.from_scene(path), 0.0)

    def check(self) -> List[str]:
        """Checks the world before the first step, as ``moreau check`` does: an unintegrable
        start raises MoreauError; returns the warnings (the scene file's, then the start's:
        grains outside the walls, in a wall, on top of each other), each also issued once as a
        ``UserWarning``. The first :meth:`step` checks when this was not called."""
        return self._check(stacklevel=3)

    def _check(self, stacklevel: int) -> List[str]:
        found = self._inner.check()
        if not self._checked:
            self._checked = True
            for w in found:
                warnings.warn(w, UserWarning, stacklevel=stacklevel)
        return found

    @property
    def notes(self) -> List[str]:
        """What loading the scene file did that it does not spell out (a grains file numbered in
        rows: ``moreau run``'s ``note:`` lines); empty for a simulation built from a World."""
        return self._inner.notes()

    def set_device(self, device: str = "cpu", threads: int = 0) -> str:
        """Solves the steps on ``device`` (cpu, gpu, auto) with ``threads`` CPU threads (0: all
        cores); returns the device chosen and why."""
        return self._inner.set_device(device, threads)

    def step(self) -> Dict[str, Any]:
        """Advances one step; returns its report (contacts, iterations, error, converged,
        stop_reason, max_penetration, kinetic_energy, dissipated_energy, boundary_work, seconds, …). A step that blows up raises MoreauError and
        the simulation keeps its last good state. The first step checks the world (:meth:`check`)."""
        if not self._checked:
            self._check(stacklevel=3)
        return self._inner.step()

    def measures(self) -> Dict[str, Any]:
        """packing_fraction, coordination, neighbours, rattlers, stress_xx, stress_yy, stress_xy, fabric_xx,
        fabric_yy, fabric_xy, anisotropy of the current state (definitions in README,
        "Simulating a scene")."""
        return self._inner.measures()

    def height_profile(self, thickness: Optional[float] = None) -> Dict[str, np.ndarray]:
        """The moving grains by height, in layers ``thickness`` high (default: one mean
        diameter) from the floor of the region they occupy to the top grain: ``y_low``,
        ``y_high``, ``grains``, ``solid_fraction``, mass-weighted mean ``vx``, ``vy``, ``spin``
        and ``velocity_fluctuation`` (``sqrt(<|v - mean|^2>)``), an array each, bottom first."""
        layers = self._inner.height_profile(thickness)
        keys = ("y_low", "y_high", "grains", "solid_fraction", "vx", "vy", "spin", "velocity_fluctuation")
        return {k: np.array([layer[k] for layer in layers], dtype=np.int64 if k == "grains" else np.float64)
                for k in keys}

    @property
    def time(self) -> float:
        return self._inner.time

    @property
    def steps_done(self) -> int:
        return self._inner.steps_done

    @property
    def body_count(self) -> int:
        return self._inner.body_count

    @property
    def positions(self) -> np.ndarray:
        """Centres, N × 2."""
        return _from(self._inner.positions(), "<f8", 2)

    @property
    def velocities(self) -> np.ndarray:
        """Velocities, N × 2."""
        return _from(self._inner.velocities(), "<f8", 2)

    @property
    def angles(self) -> np.ndarray:
        """Angles, N (0 without the effect rotation)."""
        return _from(self._inner.angles(), "<f8")

    @property
    def spins(self) -> np.ndarray:
        """Spins, N (0 without the effect rotation)."""
        return _from(self._inner.spins(), "<f8")

    def contacts(self) -> Dict[str, np.ndarray]:
        """The last step's contacts as arrays: ``body`` and ``other`` (K; ``other`` is a wall's
        index where ``other_is_wall``), ``point``, ``normal`` (from other to body) and
        ``impulse`` (normal, tangential) K × 2, ``gap`` (K, negative: overlap) and ``status``
        (K: 0 open, 1 stick, 2 slide with r_t = +μ r_n, 3 slide with r_t = −μ r_n)."""
        c = self._inner.contacts()
        return {
            "body": _from(c["body"], "<i8"),
            "other": _from(c["other"], "<i8"),
            "other_is_wall": _from(c["other_is_wall"], "u1").astype(bool),
            "point": _from(c["point"], "<f8", 2),
            "normal": _from(c["normal"], "<f8", 2),
            "impulse": _from(c["impulse"], "<f8", 2),
            "gap": _from(c["gap"], "<f8"),
            "status": _from(c["status"], "<u4"),
        }

    def wall_loads(self) -> Dict[str, np.ndarray]:
        """The grains' mean load on each wall over the last step: ``force`` (W × 2, N) and
        ``moment`` about the wall's centre (W, N·m, counter-clockwise positive)."""
        return self._loads(self._inner.wall_loads())

    def body_loads(self) -> Dict[str, np.ndarray]:
        """The contacts' mean load on each body over the last step: ``force`` (N × 2) and
        ``moment`` about the body's centre (N)."""
        return self._loads(self._inner.body_loads())

    @staticmethod
    def _loads(d: Dict[str, bytes]) -> Dict[str, np.ndarray]:
        return {"force": _from(d["force"], "<f8", 2), "moment": _from(d["moment"], "<f8")}

    def walls(self) -> Dict[str, np.ndarray]:
        """Every wall's frame and motion: ``center`` and ``velocity`` (W × 2), ``angle`` and
        ``spin`` (W)."""
        w = self._inner.walls()
        return {
            "center": _from(w["center"], "<f8", 2),
            "angle": _from(w["angle"], "<f8"),
            "velocity": _from(w["velocity"], "<f8", 2),
            "spin": _from(w["spin"], "<f8"),
        }

    def set_wall_motion(self, wall: int, velocity: Sequence[float], spin: float = 0.0) -> None:
        """A wall's velocity (m/s) and spin about its centre (rad/s) from the next step on: a
        piston or a shear box driven by the host (the world needs ``moving_walls``)."""
        self._inner.set_wall_motion(wall, tuple(velocity), spin)

    def material(self, name: str) -> int:
        return self._inner.material(name)

    def set_velocity(self, body: int, velocity: Sequence[float]) -> None:
        """Sets a body's velocity from the next step on; a fixed body keeps it (it is driven)."""
        self._inner.set_velocity(body, tuple(velocity))

    def set_spin(self, body: int, spin: float) -> None:
        self._inner.set_spin(body, spin)

    def apply_impulse(self, body: int, impulse: Sequence[float], at: Sequence[float]) -> None:
        """An impulse (N·s) at the world point ``at``, applied at once."""
        self._inner.apply_impulse(body, tuple(impulse), tuple(at))

    def apply_force(self, body: int, force: Sequence[float], torque: float = 0.0) -> None:
        """A force (N) and a torque (N·m) acting during the next step only."""
        self._inner.apply_force(body, tuple(force), torque)

    def add_disk(self, center: Sequence[float], radius: float, material: str,
                 velocity: Sequence[float] = (0.0, 0.0), spin: float = 0.0, fixed: bool = False,
                 tag: int = 0, **drive: Any) -> int:
        """Adds a disk between steps (a fixed one moves only at its velocity and spin); returns
        its index. ``drive``: ``World.add_disk``'s keywords ``force``, ``lock_rotation``,
        ``mass``, ``hold_velocity``, which make a piston or a driven plate."""
        return self._inner.add_disk(tuple(center), radius, material, tuple(velocity), spin, fixed, tag, **drive)

    def add_polygon(self, center: Sequence[float], vertices: Sequence[Sequence[float]], material: str,
                    angle: float = 0.0, velocity: Sequence[float] = (0.0, 0.0), spin: float = 0.0,
                    fixed: bool = False, tag: int = 0, **drive: Any) -> int:
        """Adds a polygon between steps (vertices relative to ``center``: convex in any order, or a
        concave outline in either direction); returns its index. ``drive`` as ``add_disk``'s."""
        return self._inner.add_polygon(tuple(center), [tuple(v) for v in vertices], material, angle,
                                       tuple(velocity), spin, fixed, tag, **drive)

    def add_clump(self, center: Sequence[float], disks: Sequence[Sequence[float]], material: str,
                  angle: float = 0.0, velocity: Sequence[float] = (0.0, 0.0), spin: float = 0.0,
                  fixed: bool = False, tag: int = 0, **drive: Any) -> int:
        """Adds a clump between steps: disks ``(x, y, r)`` (centres relative to ``center``) that
        overlap into one rigid grain; returns its index. ``drive`` as ``add_disk``'s."""
        return self._inner.add_clump(tuple(center), [tuple(d) for d in disks], material, angle,
                                     tuple(velocity), spin, fixed, tag, **drive)

    def remove_body(self, body: int) -> None:
        """Removes a body; the bodies after it move down one index, its contacts go."""
        self._inner.remove_body(body)

    def write_checkpoint(self, path: Path, scene: Optional[Path] = None) -> None:
        """Writes the state between steps as a checkpoint (JSON); with ``scene``, stamped with
        that scene file's fingerprint, so that ``moreau run SCENE --restart`` goes on from it."""
        self._inner.write_checkpoint(os.fspath(path), None if scene is None else os.fspath(scene))

    def restore(self, path: Path, scene: Optional[Path] = None) -> None:
        """Goes back to a checkpoint (this simulation's, or ``moreau run``'s): the steps after it
        are those the first run took. With ``scene``, the checkpoint must come from that file."""
        self._inner.restore(os.fspath(path), None if scene is None else os.fspath(scene))

    def keep_problems(self, keep: bool = True) -> None:
        """Keep each step's contact problem for :meth:`last_problem`."""
        self._inner.keep_problems(keep)

    def last_problem(self) -> Optional[Problem]:
        """The last step's contact problem (matrix-free W), with keep_problems on."""
        p = self._inner.last_problem()
        return None if p is None else Problem(p, None, None)
