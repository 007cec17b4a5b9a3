"""Typed stubs of the Rust extension ``upm._core`` (checked by ``mypy.stubtest``)."""

from collections.abc import Callable
from typing import final

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "Field",
    "MChipRun",
    "Plans",
    "PlateMotion",
    "Run",
    "WaveformBatch",
    "__version__",
    "_panic_for_test",
    "apply_rays",
    "asymptotic_field",
    "average_field",
    "axis_response",
    "axis_steps",
    "bang_bang_efficiency",
    "bang_bang_feed_rate",
    "bang_bang_force",
    "bang_bang_velocity_range",
    "center_of_rotation",
    "cor_from_accelerometers",
    "corner_excursions",
    "coverage_centroids",
    "disk_friction",
    "distance_sum",
    "drift_field",
    "edge_penalty",
    "flow_error",
    "force_table",
    "gamma",
    "harmonic_fit",
    "jet_field",
    "mchip_simulate",
    "motors_for",
    "normalized_drive",
    "overlap_penalty",
    "polygon_gauge",
    "polygon_geometry",
    "polygon_wrench",
    "positive_force",
    "priorities",
    "rotation_curl",
    "rotation_field",
    "simd_info",
    "simulate",
    "solve",
    "solve_batch",
    "theorem1_force",
    "two_harmonic_feed_rate",
    "two_harmonic_force_at_rest",
    "velocity_amplitudes",
    "velocity_from_fit",
    "viscous_gain",
]

__version__: str

_F = NDArray[np.float64]

@final
class WaveformBatch:
    @staticmethod
    def harmonics(cos: _F, sin: _F, frequency: _F) -> WaveformBatch: ...
    @staticmethod
    def bang_bang(z: _F, a_max: _F, period: _F) -> WaveformBatch: ...
    def __len__(self) -> int: ...
    def period(self) -> _F: ...
    def evaluate(self, t: _F, derivative: int) -> _F: ...
    def feed_rate(self, threads: int | None = None) -> _F: ...
    def mean_force(self, part_velocity: _F, threads: int | None = None) -> _F: ...
    def velocity_range(self) -> tuple[_F, _F]: ...

def disk_friction(phi: _F) -> tuple[_F, _F]: ...
def polygon_geometry(
    vertices: _F, name: str = "vertices", support: _F | None = None
) -> tuple[float, _F, float, float, float, _F, _F, _F | None]: ...
def polygon_wrench(
    vertices: _F,
    twists: _F,
    threads: int | None = None,
    load: tuple[float, float] = ...,
    support: _F | None = None,
) -> _F: ...
def polygon_gauge(
    vertices: _F,
    wrenches: _F,
    threads: int | None = None,
    load: tuple[float, float] = ...,
    support: _F | None = None,
) -> tuple[_F, _F]: ...
def force_table(n1: int, n2: int, psi: _F, b: _F, threads: int | None = None) -> _F: ...
def theorem1_force(n1: int, n2: int, psi: _F) -> _F: ...
def bang_bang_feed_rate(z: _F, a_max: _F, period: _F) -> _F: ...
def bang_bang_force(z: _F, part_velocity: _F, a_max: _F, period: _F) -> _F: ...
def bang_bang_velocity_range(z: _F, a_max: _F, period: _F) -> tuple[_F, _F]: ...
def bang_bang_efficiency(z: _F) -> tuple[_F, _F]: ...
def viscous_gain(a_max: _F, period: _F, mu_m_g: _F) -> _F: ...
def two_harmonic_feed_rate(b: _F, phi: _F, amplitude: _F) -> _F: ...
def two_harmonic_force_at_rest(b: _F) -> _F: ...
def gamma(b: _F) -> _F: ...
def normalized_drive(b: _F, a_max: _F, period: _F) -> tuple[_F, _F, _F, _F, _F, _F]: ...
def coverage_centroids(
    cover: NDArray[np.float32], origins: _F, centres: _F, radius: float, iterations: int
) -> tuple[_F, _F, _F]: ...
def _panic_for_test() -> None: ...

@final
class PlateMotion:
    @staticmethod
    def translation(direction: tuple[float, float], waveform: WaveformBatch) -> PlateMotion: ...
    @staticmethod
    def rotation(center: tuple[float, float], waveform: WaveformBatch) -> PlateMotion: ...
    @staticmethod
    def jet(
        center: tuple[float, float],
        direction: tuple[float, float],
        rho: float,
        amplitude: float,
        frequency: float,
    ) -> PlateMotion: ...
    @staticmethod
    def spatial(frequency: float, terms: list[list[tuple[int, float, float]]]) -> PlateMotion: ...
    def is_spatial(self) -> bool: ...
    def normal(self, t: _F) -> _F: ...
    @staticmethod
    def pulses(
        kind: NDArray[np.int64],
        center: _F,
        direction: _F,
        amplitude: _F,
        frequency: _F,
        attack: _F,
        sustain: _F,
        rho: float,
    ) -> list[PlateMotion]: ...
    @staticmethod
    def rest(duration: float) -> PlateMotion: ...
    @staticmethod
    def from_samples(t: _F, u: _F) -> PlateMotion: ...
    @staticmethod
    def sequence(motions: list[PlateMotion]) -> PlateMotion: ...
    def for_duration(self, seconds: float) -> PlateMotion: ...
    def with_envelope(self, attack: float, sustain: float, decay: float) -> PlateMotion: ...
    def duration(self) -> float | None: ...
    def max_frequency(self) -> float: ...
    def __len__(self) -> int: ...
    def evaluate(self, t: _F) -> tuple[_F, _F]: ...
    def displacement(self) -> list[float]: ...

@final
class Run:
    """A simulation's arrays, batch axis first (what ``simulate`` returns)."""
    @property
    def t(self) -> _F: ...
    @property
    def positions(self) -> _F: ...
    @property
    def velocities(self) -> _F: ...
    @property
    def stuck(self) -> NDArray[np.bool_]: ...
    @property
    def angles(self) -> _F: ...
    @property
    def spins(self) -> _F: ...
    @property
    def left_time(self) -> _F: ...
    @property
    def left_plate(self) -> NDArray[np.bool_]: ...
    @property
    def flight(self) -> _F: ...

def simulate(
    motions: list[PlateMotion],
    positions: _F,
    velocities: _F | None,
    mu: _F,
    mu_s: _F,
    radius: _F | None,
    angle: _F | None,
    spin: _F | None,
    *,
    dt: float,
    duration: float,
    g: float,
    plate_size: float | None,
    record_every: int,
    threads: int | None = None,
    progress: Callable[[int], object] | None = None,
    contacts: bool = False,
    restitution: float = 0.5,
    part_friction: float = 0.3,
    walls: _F | None = None,
    walls_move_with_plate: bool = False,
    mass: _F | None = None,
    contact_iterations: int = 4,
    world_mu: _F | None = None,
    world_mu_s: _F | None = None,
    polygons: list[tuple[int, _F, _F | None]] | None = None,
    world_positions: _F | None = None,
    world_angles: _F | None = None,
    tilt: tuple[float, float] = ...,
    friction_map: _F | None = None,
) -> Run: ...
def simd_info() -> tuple[str, list[str]]: ...

@final
class Field:
    """A field at M points (what ``drift_field`` and ``asymptotic_field`` return)."""
    @property
    def velocity(self) -> _F: ...
    @property
    def max_accel(self) -> _F: ...
    @property
    def lift(self) -> _F: ...
    @property
    def work(self) -> NDArray[np.uint64]: ...
    @property
    def converged(self) -> NDArray[np.bool_]: ...

def drift_field(
    motion: PlateMotion,
    points: _F,
    *,
    mu: float,
    mu_s: float,
    g: float,
    steps: int,
    tol: float,
    max_periods: int,
    threads: int | None = None,
) -> Field: ...
def asymptotic_field(
    motion: PlateMotion, points: _F, *, g: float, samples: int, threads: int | None = None
) -> Field: ...

_I = NDArray[np.int64]

@final
class Plans:
    """Solved systems, batch axis first (what ``solve`` and ``solve_batch`` return)."""
    @property
    def strengths(self) -> _F: ...
    @property
    def order(self) -> _I: ...
    @property
    def predicted(self) -> _F: ...
    @property
    def predicted_curls(self) -> _F: ...
    @property
    def residual(self) -> _F: ...
    @property
    def bound_cost(self) -> _F: ...
    @property
    def singular_values(self) -> _F: ...
    @property
    def rank(self) -> _I: ...
    @property
    def condition_number(self) -> _F: ...

def solve(
    parts: _F,
    targets: _F,
    centers: _F,
    curl_points: _F,
    curls: _F,
    mu_m_g: float | None,
    rcond: float | None,
    damping: float,
    max_strength: float | None,
) -> Plans: ...
def solve_batch(
    parts: _F,
    targets: _F,
    centers: _F,
    curl_points: _F,
    curls: _F,
    mu_m_g: float | None,
    rcond: float | None,
    damping: float,
    max_strength: float | None,
) -> Plans: ...
def priorities(strengths: _F, parts: _F, centers: _F) -> _F: ...
def flow_error(strengths: _F, parts: _F, centers: _F, order: list[int], exact: bool) -> _F: ...
def rotation_field(points: _F, center: tuple[float, float]) -> _F: ...
def rotation_curl(points: _F, center: tuple[float, float]) -> _F: ...
def jet_field(
    points: _F,
    center: tuple[float, float],
    direction: tuple[float, float],
    rho: float,
    tol: float,
    threads: int | None = None,
) -> _F: ...
def average_field(
    motion: PlateMotion, points: _F, part_velocity: _F, tol: float, threads: int | None = None
) -> _F: ...
def motors_for(
    mass: float, inertia: float, lever: float, u: tuple[float, float, float], limit: float | None
) -> tuple[float, float, float, float]: ...
def velocity_amplitudes(
    mass: float, inertia: float, lever: float, motors: tuple[float, float, float, float]
) -> tuple[float, float, float]: ...
def center_of_rotation(u: tuple[float, float, float]) -> tuple[tuple[float, float], float]: ...
def axis_steps(
    mass: float, damping: float, stiffness: float, forces: _F, dt: float, q0: _F, v0: _F
) -> tuple[_F, _F, _F]: ...
def axis_response(mass: float, damping: float, stiffness: float, w: _F) -> tuple[float | None, _F, _F]: ...
def harmonic_fit(
    samples: _F, sample_rate: float, frequency: float, multiples: list[float]
) -> tuple[_F, float, float]: ...
def velocity_from_fit(coefficients: _F, frequency: float, multiples: list[float]) -> _F: ...
def positive_force(coefficients: _F) -> NDArray[np.bool_]: ...
def apply_rays(q: _F, radii: _F, centres: _F, turn: _F, shift: _F) -> NDArray[np.float64]: ...
def edge_penalty(
    q: _F,
    half: float,
    band: float,
    weight: float,
    lost: float,
    guard: float,
    start: _F | None = None,
    spread: float = 0.0,
) -> NDArray[np.float64]: ...
def distance_sum(q: _F, targets: _F, slack: float, bend: float) -> NDArray[np.float64]: ...
def overlap_penalty(q: _F, reach: float) -> NDArray[np.float64]: ...
def corner_excursions(
    w_re: _F, w_im: _F, g_re: _F, g_im: _F, samples: int, corners: _F
) -> NDArray[np.float64]: ...
def cor_from_accelerometers(
    first: _F,
    second: _F,
    r1: tuple[float, float],
    sample_rate: float,
    frequency: float,
    multiples: list[float],
) -> tuple[tuple[float, float], _F, float]: ...

@final
class MChipRun:
    """An M-Chip run's arrays (what ``mchip_simulate`` returns)."""
    @property
    def t(self) -> _F: ...
    @property
    def positions(self) -> _F: ...
    @property
    def velocities(self) -> _F: ...
    @property
    def orientations(self) -> _F: ...
    @property
    def angular_velocities(self) -> _F: ...
    @property
    def angles(self) -> _F: ...
    @property
    def collisions(self) -> _F: ...
    @property
    def energy(self) -> _F: ...
    @property
    def joint(self) -> list[float]: ...

def mchip_simulate(
    *,
    rows: int,
    cols: int,
    slab: tuple[float, float, float],
    gap: float,
    ridge_distance: float,
    ridge_height: float,
    ridge_width: float,
    density: float,
    natural_frequency: float,
    quality: float,
    part_size: tuple[float, float, float],
    part_mass: float,
    friction: float,
    restitution: float,
    frequency: float,
    duty: float,
    torque: float | None,
    peak_angle: float,
    scheme: str,
    tau: int,
    delta: int,
    phases: list[float],
    dt: float,
    duration: float,
    record_every: int,
    external_force: tuple[float, float],
    iterations: int,
    part_start: tuple[float, float],
    drop_height: float,
    initial_angle: float,
    part: bool,
) -> MChipRun: ...
