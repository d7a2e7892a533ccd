"""Type stubs of moreau's compiled module. Arrays cross as bytes of little-endian numbers; the
package's ``__init__`` turns them into numpy arrays."""

from os import PathLike
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

_Path = Union[str, PathLike[str]]
_Vec = Tuple[float, float]

__version__: str

class MoreauError(Exception): ...

class Problem:
    @staticmethod
    def from_csr(n: int, indptr: bytes, indices_: bytes, data: bytes, q: bytes, mu: bytes) -> Problem: ...
    @property
    def n_contacts(self) -> int: ...
    @property
    def q(self) -> bytes: ...
    @property
    def mu(self) -> bytes: ...
    @property
    def matrix_free(self) -> bool: ...
    def velocity(self, r: bytes) -> bytes: ...
    def write_fc2d(self, path: _Path, sparse: bool = True) -> None: ...

def read_fc2d(path: _Path) -> Problem: ...
def deposit(disks: int, mu: float, seed: int) -> Problem: ...
def solve(
    problem: Problem,
    solver: str,
    tol: float,
    max_iter: int,
    device: str,
    threads: int,
    r0: Optional[bytes] = None,
    history_every: int = 0,
    anderson: int = 0,
    focus: int = 0,
    criterion: str = "natural",
    ordering: str = "forward",
    omega: float = 1.0,
) -> Dict[str, Any]: ...

class World:
    def __init__(
        self,
        materials: Sequence[Tuple[str, float]],
        friction: float = 0.0,
        restitution: float = 0.0,
        cohesion: float = 0.0,
        gravity: Optional[_Vec] = None,
        rotation: bool = False,
        moving_walls: bool = False,
    ) -> None: ...
    def set_pass_through(self, a: str, b: str, through: bool = True) -> None: ...
    def set_interaction(
        self,
        a: str,
        b: str,
        friction: float = 0.0,
        restitution: float = 0.0,
        cohesion: float = 0.0,
        rolling_resistance: float = 0.0,
    ) -> None: ...
    def add_disk(
        self,
        center: _Vec,
        radius: float,
        material: str,
        velocity: _Vec = (0.0, 0.0),
        spin: float = 0.0,
        fixed: bool = False,
        tag: int = 0,
        *,
        force: _Vec = (0.0, 0.0),
        lock_rotation: bool = False,
        mass: Optional[float] = None,
        hold_velocity: Sequence[str] = (),
    ) -> int: ...
    def add_grains(self, path: _Path, material: str, order: str = "auto") -> List[int]: ...
    def add_polygon(
        self,
        center: _Vec,
        vertices: List[_Vec],
        material: str,
        angle: float = 0.0,
        velocity: _Vec = (0.0, 0.0),
        spin: float = 0.0,
        fixed: bool = False,
        tag: int = 0,
        *,
        force: _Vec = (0.0, 0.0),
        lock_rotation: bool = False,
        mass: Optional[float] = None,
        hold_velocity: Sequence[str] = (),
    ) -> int: ...
    def add_clump(
        self,
        center: _Vec,
        disks: List[Tuple[float, float, float]],
        material: str,
        angle: float = 0.0,
        velocity: _Vec = (0.0, 0.0),
        spin: float = 0.0,
        fixed: bool = False,
        tag: int = 0,
        *,
        force: _Vec = (0.0, 0.0),
        lock_rotation: bool = False,
        mass: Optional[float] = None,
        hold_velocity: Sequence[str] = (),
    ) -> int: ...
    def add_wall(self, a: _Vec, b: _Vec, material: str, velocity: _Vec = (0.0, 0.0)) -> int: ...
    def add_polygon_wall(
        self, vertices: Sequence[_Vec], material: str, velocity: _Vec = (0.0, 0.0), spin: float = 0.0
    ) -> int: ...
    def add_drum(self, center: _Vec, radius: float, sides: int, material: str, spin: float = 0.0) -> List[int]: ...
    def set_periodic(self, x0: float, x1: float) -> None: ...
    @property
    def periodic(self) -> Optional[Tuple[float, float]]: ...
    @property
    def body_count(self) -> int: ...

class Simulation:
    def __init__(
        self,
        world: World,
        h: float,
        theta: float = 0.5,
        alert: Optional[float] = None,
        solver: str = "nlgs",
        tol: float = 1e-4,
        max_iter: int = 10000,
        anderson: int = 0,
        focus: int = 0,
        criterion: str = "natural",
        ordering: str = "forward",
        projection_slack: Optional[float] = None,
        omega: float = 1.0,
    ) -> None: ...
    def set_solver(
        self,
        solver: Optional[str] = None,
        tol: Optional[float] = None,
        max_iter: Optional[int] = None,
        criterion: Optional[str] = None,
        ordering: Optional[str] = None,
        anderson: Optional[int] = None,
        focus: Optional[int] = None,
        omega: Optional[float] = None,
        block_sweeps: Optional[int] = None,
    ) -> None: ...
    def set_time_step(self, h: float) -> None: ...
    @property
    def time_step(self) -> float: ...
    def solver_settings(self) -> Dict[str, Any]: ...
    @staticmethod
    def from_scene(path: _Path) -> Simulation: ...
    def check(self) -> List[str]: ...
    def notes(self) -> List[str]: ...
    def set_device(self, device: str = "cpu", threads: int = 0) -> str: ...
    def step(self) -> Dict[str, Any]: ...
    def measures(self) -> Dict[str, Any]: ...
    def height_profile(self, thickness: Optional[float] = None) -> List[Dict[str, Any]]: ...
    @property
    def time(self) -> float: ...
    @property
    def steps_done(self) -> int: ...
    @property
    def body_count(self) -> int: ...
    def material(self, name: str) -> int: ...
    def positions(self) -> bytes: ...
    def velocities(self) -> bytes: ...
    def angles(self) -> bytes: ...
    def spins(self) -> bytes: ...
    def contacts(self) -> Dict[str, bytes]: ...
    def wall_loads(self) -> Dict[str, bytes]: ...
    def body_loads(self) -> Dict[str, bytes]: ...
    def walls(self) -> Dict[str, bytes]: ...
    def set_wall_motion(self, wall: int, velocity: _Vec, spin: float = 0.0) -> None: ...
    def set_velocity(self, body: int, velocity: _Vec) -> None: ...
    def set_spin(self, body: int, spin: float) -> None: ...
    def apply_impulse(self, body: int, impulse: _Vec, at: _Vec) -> None: ...
    def apply_force(self, body: int, force: _Vec, torque: float = 0.0) -> None: ...
    def add_disk(
        self,
        center: _Vec,
        radius: float,
        material: str,
        velocity: _Vec = (0.0, 0.0),
        spin: float = 0.0,
        fixed: bool = False,
        tag: int = 0,
        *,
        force: _Vec = (0.0, 0.0),
        lock_rotation: bool = False,
        mass: Optional[float] = None,
        hold_velocity: Sequence[str] = (),
    ) -> int: ...
    def add_polygon(
        self,
        center: _Vec,
        vertices: List[_Vec],
        material: str,
        angle: float = 0.0,
        velocity: _Vec = (0.0, 0.0),
        spin: float = 0.0,
        fixed: bool = False,
        tag: int = 0,
        *,
        force: _Vec = (0.0, 0.0),
        lock_rotation: bool = False,
        mass: Optional[float] = None,
        hold_velocity: Sequence[str] = (),
    ) -> int: ...
    def add_clump(
        self,
        center: _Vec,
        disks: List[Tuple[float, float, float]],
        material: str,
        angle: float = 0.0,
        velocity: _Vec = (0.0, 0.0),
        spin: float = 0.0,
        fixed: bool = False,
        tag: int = 0,
        *,
        force: _Vec = (0.0, 0.0),
        lock_rotation: bool = False,
        mass: Optional[float] = None,
        hold_velocity: Sequence[str] = (),
    ) -> int: ...
    def remove_body(self, body: int) -> None: ...
    def write_checkpoint(self, path: _Path, scene: Optional[_Path] = None) -> None: ...
    def restore(self, path: _Path, scene: Optional[_Path] = None) -> None: ...
    def keep_problems(self, keep: bool) -> None: ...
    def last_problem(self) -> Optional[Problem]: ...
