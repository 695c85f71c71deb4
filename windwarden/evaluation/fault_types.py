"""The fault types whose detectability ``windwarden detectability`` sweeps and whose sizes random scenarios draw.

A *fault type* is one family of faults of one plant kind with one size variable: a speed-sensor offset in units
of the sensor's noise σ, a speed-sensor gain error in %, a farm turbine's power loss to debris in %, and so on.
It says which targets a fault of that type may hit (one is drawn per fault), how a size and a sign become a
scenario fault (``FaultType.faults``), the default size grid of the sweep and why (``grid_reason``, from the
physics of the signal and its noise), and the upper bound random scenarios draw sizes to (``upper``).

σ is the sensor's noise standard deviation under the scenario's noise convention (``wwcore.channels.noise_std``,
PARAMETERS.md a.3): in the papers' reading ω_r 0.0251 rad/s, ω_g 0.05 rad/s, β 0.2 deg, τ_g 90 N m.

Also here: the operating wind range of each plant kind and the helpers that place fault windows at random times
and hold a drawn mean wind over each window (shared by the sweep and the random-scenario generator).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from wwcore.channels import SENSOR_INDEX, SENSORS, noise_std
from wwcore.scenario import FaultKind, FaultSpec

TICK_S = 0.01
"""Fault times are drawn on the plants' 100 Hz tick, so a fault's first tick is its start (no fractional delay)."""


@dataclass(frozen=True)
class WindRange:
    """Mean winds a plant kind is scored over, drawn uniformly in [lo, hi] m/s; ``rated`` splits the bands."""

    lo: float
    hi: float
    rated: float | None
    reason: str


WIND_RANGES: dict[str, WindRange] = {
    "turbine": WindRange(
        4.0,
        25.0,
        12.0,
        "cut-in 4 m/s to cut-out 25 m/s, the usual limits of a multi-MW turbine (the benchmark states neither; "
        "its region-2 law and pitch loop run over the whole span); rated ≈ 12 m/s (PARAMETERS.md a.1)",
    ),
    "farm": WindRange(
        4.0,
        25.0,
        12.0,
        "the same turbines as the single benchmark turbine: cut-in 4 m/s to cut-out 25 m/s, free stream at the mast",
    ),
    "hydro": WindRange(
        5.0,
        9.5,
        None,
        "partial load, the only region seed 003's controller and observer cover: from 5 m/s (ω_r ≈ 0.6 rad/s at "
        "λ_opt) to 9.5 m/s, below rated (≈ 10.6 m/s at ω_r 1.267 rad/s, λ_opt 7.55); the shipped scenarios use 7.5",
    ),
}


@dataclass(frozen=True)
class FaultType:
    """One swept family of faults (module docstring)."""

    name: str
    kind: str  # plant kind
    label: str
    unit: str  # of the size
    targets: tuple[str, ...]  # one is drawn per fault
    fault_kind: FaultKind
    rule: str  # how a size becomes a fault value: sigma, gain_pct, loss_pct, signed, magnitude
    sizes: tuple[float, ...]  # default sweep grid
    grid_reason: str
    upper: float  # random scenarios draw sizes up to this
    upper_reason: str
    window_s: float  # length of a sweep window
    sigma_channel: str | None = None  # the sensor whose noise σ is the unit (rule "sigma")

    def sigma(self, noise_convention: str) -> float:
        """The σ of the size unit (rule ``sigma``), in the fault value's own unit."""
        assert self.sigma_channel is not None
        return noise_std(SENSORS[SENSOR_INDEX[self.sigma_channel]], noise_convention)

    def value(self, size: float, sign: float, noise_convention: str = "sigma") -> float:
        """The scenario fault's ``value`` for a size (> 0) and a sign (±1; ignored where the type has none)."""
        match self.rule:
            case "sigma":
                return sign * size * self.sigma(noise_convention)
            case "gain_pct":
                return 1.0 + sign * size / 100.0
            case "loss_pct":
                return 1.0 - size / 100.0
            case "signed":
                return sign * size
            case "magnitude":
                return size
        raise ValueError(f"unknown size rule {self.rule!r}")

    def size_of(self, value: float, noise_convention: str = "sigma") -> float:
        """The size a fault value has (the inverse of ``value``)."""
        match self.rule:
            case "sigma":
                return abs(value) / self.sigma(noise_convention)
            case "gain_pct":
                return abs(value - 1.0) * 100.0
            case "loss_pct":
                return (1.0 - value) * 100.0
        return abs(value)

    @property
    def value_unit(self) -> str:
        """The unit of the scenario fault's ``value``."""
        if self.rule == "sigma":
            assert self.sigma_channel is not None
            return SENSORS[SENSOR_INDEX[self.sigma_channel]].unit
        return {"gain_pct": "gain", "loss_pct": "power factor"}.get(self.rule, self.unit)

    @property
    def signed(self) -> bool:
        return self.rule in {"sigma", "gain_pct", "signed"}

    def fault(
        self,
        size: float,
        *,
        target: str,
        sign: float,
        start_s: float,
        end_s: float,
        turbine: int = 1,
        name: str | None = None,
        noise_convention: str = "sigma",
    ) -> FaultSpec:
        value = self.value(size, sign, noise_convention)
        return FaultSpec(
            target=target,
            kind=self.fault_kind,
            value=round(value, 9),
            start_s=start_s,
            end_s=end_s,
            turbine=turbine,
            name=name,
        )

    def draw_target(self, rng: np.random.Generator) -> tuple[str, float]:
        """A target and a sign, uniformly."""
        target = self.targets[int(rng.integers(len(self.targets)))]
        return target, (1.0 if rng.random() < 0.5 else -1.0) if self.signed else 1.0


_SPEED_R = ("omega_r_m1", "omega_r_m2")
_SPEED_G = ("omega_g_m1", "omega_g_m2")
_PITCH = tuple(f"beta_{i}_m{j}" for i in (1, 2, 3) for j in (1, 2))
_SPEED_SIGMA_GRID = (1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 6.0, 10.0)

FAULT_TYPES: tuple[FaultType, ...] = (
    FaultType(
        "speed-rotor-offset",
        "turbine",
        "rotor-speed sensor offset",
        "σ",
        _SPEED_R,
        FaultKind.OFFSET,
        "sigma",
        _SPEED_SIGMA_GRID,
        "a per-sample test of the two sensors' difference (noise √2 σ) at a false-alarm budget of 1e-5 per sample "
        "needs ≈ 4.4·√2 ≈ 6 σ; tests over windows see less: the grid spans 1 σ (buried in noise) to 10 σ, finer "
        "around 2–3 σ where a development sweep crossed 50 %",
        20.0,
        "20 σ = 0.5 rad/s, 30 % of rated rotor speed: beyond it a fault is obvious to any test",
        10.0,
        "omega_r_m1",
    ),
    FaultType(
        "speed-generator-offset",
        "turbine",
        "generator-speed sensor offset",
        "σ",
        _SPEED_G,
        FaultKind.OFFSET,
        "sigma",
        _SPEED_SIGMA_GRID,
        "as the rotor-speed offset: σ-scaled, 1 σ to 10 σ around the ≈ 6 σ of a per-sample parity test",
        20.0,
        "20 σ = 1 rad/s, 0.6 % of rated generator speed",
        10.0,
        "omega_g_m1",
    ),
    FaultType(
        "speed-rotor-gain",
        "turbine",
        "rotor-speed sensor gain error",
        "%",
        _SPEED_R,
        FaultKind.GAIN,
        "gain_pct",
        (1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 6.0, 10.0),
        "a gain error g − 1 moves the reading by (g − 1)·ω_r: 1 % is 0.68 σ at rated rotor speed (1.705 rad/s) "
        "and 0.2 σ at 4 m/s (ω_r ≈ 0.5 rad/s), so the grid reaches 10 %, the benchmark's fault 5 (gain 1.1); a "
        "development sweep above rated went from none detected at 2 % to all at 3 %",
        10.0,
        "10 %, the benchmark's fault 5 (gain 1.1 on ω_r,m2)",
        10.0,
    ),
    FaultType(
        "speed-generator-gain",
        "turbine",
        "generator-speed sensor gain error",
        "%",
        _SPEED_G,
        FaultKind.GAIN,
        "gain_pct",
        (0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5, 1.0),
        "ω_g is read 19 times more finely than ω_r (σ 0.05 rad/s at 48–162 rad/s): 0.1 % is 3.2 σ at rated "
        "generator speed and 1 σ at 4 m/s, so the grid spans 0.02 % to 1 %",
        10.0,
        "10 %, the benchmark's gain 0.9 on ω_g,m2",
        10.0,
    ),
    FaultType(
        "pitch-sensor-offset",
        "turbine",
        "pitch sensor offset",
        "σ",
        _PITCH,
        FaultKind.OFFSET,
        "sigma",
        (0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 3.0, 6.0),
        "the blade's two sensors' parity (noise √2 σ) averaged over 10 ticks: ≈ 2 σ at its 1e-5 budget; the "
        "offset also moves the blade through the pitch loop in region 3; 0.5 σ to 6 σ, finer around the 1–1.5 σ "
        "where a development sweep crossed",
        25.0,
        "25 σ = 5 deg, the benchmark's fault 1 (β1,m1 fixed at 5 deg near 0 deg)",
        10.0,
        "beta_1_m1",
    ),
    FaultType(
        "converter-offset",
        "turbine",
        "converter torque offset",
        "σ",
        ("converter",),
        FaultKind.TORQUE_OFFSET,
        "sigma",
        (0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.6, 1.0),
        "the residual τ_g,m − τ̂_g has the torque sensor's noise σ = 90 N m per tick; CUSUMs for shifts from "
        "0.25 σ see offsets above 0.125 σ given time (a 10 s window: ≈ 0.2 σ); 0.1 σ (9 N m) to 1 σ (90 N m, about "
        "the benchmark's 100 N m)",
        11.0,
        "11 σ ≈ 1000 N m, the largest offset magnitude in the benchmark's scenario list (PARAMETERS.md a.8)",
        10.0,
        "tau_g_m",
    ),
    FaultType(
        "farm-debris",
        "farm",
        "blade debris (power loss)",
        "%",
        ("rotor",),
        FaultKind.DEBRIS,
        "loss_pct",
        (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 6.0),
        "a power loss against the turbine's power curve and its row: turbulence moves a turbine's 10 Hz power by "
        "several % while the paper's CUSUM is tuned to 2.7 %; 0.25 % to 6 % brackets the paper's 3 %",
        10.0,
        "10 %, a heavily fouled rotor; beyond it the fault would be an aerodynamic failure",
        20.0,
    ),
    FaultType(
        "farm-pitch-misalignment",
        "farm",
        "pitch misalignment (one blade)",
        "deg",
        ("pitch_actuator_1", "pitch_actuator_2", "pitch_actuator_3"),
        FaultKind.OFFSET,
        "signed",
        (0.05, 0.1, 0.15, 0.2, 0.3, 0.5, 1.0, 2.0),
        "one blade held off the collective command: it unbalances the rotor (1P) and lowers power by ∝ offset²; "
        "the paper's 0.3 deg sits mid-grid, 0.05 deg (a quarter of the pitch sensors' σ) to 2 deg",
        2.0,
        "2 deg, an order above the paper's 0.3 deg, well inside the ±5 deg a scenario allows",
        20.0,
    ),
    FaultType(
        "farm-drivetrain",
        "farm",
        "drive-train 3P transmission error",
        "mrad",
        ("drivetrain",),
        FaultKind.DRIVETRAIN_WEAR,
        "magnitude",
        (0.25, 0.5, 1.0, 2.0, 3.0, 5.0, 8.0, 12.0),
        "the 3P shaft-torque ripple is ∝ the transmission error's amplitude; the shipped 5 mrad raises the "
        "drive-train damage by a few %, so the grid spans 0.25 mrad (lost in the turbulent 3P band) to 12 mrad",
        12.0,
        "12 mrad, well inside the scenario's 20 mrad limit",
        20.0,
    ),
    FaultType(
        "hydro-pump-offset",
        "hydro",
        "pump displacement offset (u_p)",
        "stroke",
        ("u_p",),
        FaultKind.OFFSET,
        "signed",
        (0.002, 0.005, 0.01, 0.015, 0.02, 0.03, 0.05, 0.1),
        "an additive offset on the normalised pump command; the detector's threshold is max(1.5 × the largest "
        "fault-free reconstruction, 0.01) (docs/hydro.md), so the grid spans 0.002 to 0.1 around 0.01",
        0.4,
        "0.4, the paper's largest offset (Fig. 5)",
        10.0,
    ),
    FaultType(
        "hydro-motor-offset",
        "hydro",
        "motor displacement offset (u_M)",
        "stroke",
        ("u_M",),
        FaultKind.OFFSET,
        "signed",
        (0.002, 0.005, 0.01, 0.015, 0.02, 0.03, 0.05, 0.1),
        "as the pump: 0.002 to 0.1 around the 0.01 threshold floor",
        0.4,
        "0.4, the paper's largest offset (Fig. 6)",
        10.0,
    ),
)

FAULT_TYPE_BY_NAME: dict[str, FaultType] = {t.name: t for t in FAULT_TYPES}


def types_of(kind: str) -> list[FaultType]:
    return [t for t in FAULT_TYPES if t.kind == kind]


def fault_type(name: str, kind: str | None = None) -> FaultType:
    """The fault type of that name (of that plant kind, when given); unknown names raise ``KeyError`` naming the
    known ones."""
    known = types_of(kind) if kind else list(FAULT_TYPES)
    for t in known:
        if t.name == name:
            return t
    where = f" of a {kind} plant" if kind else ""
    raise KeyError(f"unknown fault type {name!r}{where}; known: {', '.join(t.name for t in known)}")


# ---- times and winds ---------------------------------------------------------------------------------------------
def on_tick(t: float) -> float:
    return round(round(t / TICK_S) * TICK_S, 2)


def place_windows(
    rng: np.random.Generator, lengths: Sequence[float], *, first_s: float, min_gap_s: float, extra_gap_s: float
) -> tuple[list[tuple[float, float]], float]:
    """Windows of the given lengths, in order, at random times: the first starts at ``first_s`` plus a uniform
    draw in [0, extra_gap_s]; each next one starts ``min_gap_s`` plus such a draw after the previous one ends.
    Returns the windows (on the tick) and the end of the run: ``min_gap_s`` plus a draw after the last window."""
    out = []
    t = first_s + rng.uniform(0.0, extra_gap_s)
    for length in lengths:
        start = on_tick(t)
        end = on_tick(start + length)
        out.append((start, end))
        t = end + min_gap_s + rng.uniform(0.0, extra_gap_s)
    return out, on_tick(t)


def held_wind(
    windows: Sequence[tuple[float, float]], levels: Sequence[float], *, settle_s: float, after_s: float
) -> list[tuple[float, float]]:
    """A mean-wind profile that holds ``levels[i]`` from ``settle_s`` before window i starts to ``after_s`` after
    it ends, and ramps linearly between; before the first it holds the first level. The gaps between windows
    must exceed ``settle_s + after_s`` (``place_windows`` with a ``min_gap_s`` larger than both ensures it)."""
    points: list[tuple[float, float]] = []
    for (start, end), v in zip(windows, levels, strict=True):
        lo, hi = round(start - settle_s, 6), round(end + after_s, 6)
        if points and lo <= points[-1][0]:
            raise ValueError(f"window at {start} s leaves no room to settle the wind after the previous one")
        points += [(max(lo, 0.0), float(v)), (hi, float(v))]
    if points and points[0][0] > 0.0:
        points.insert(0, (0.0, points[0][1]))
    return points


def draw_winds(rng: np.random.Generator, kind: str, n: int) -> list[float]:
    """n mean winds uniform over the plant kind's range, to 0.1 m/s."""
    r = WIND_RANGES[kind]
    return [round(float(v), 1) for v in rng.uniform(r.lo, r.hi, n)]


def catalogue_table() -> str:
    """The fault types as ``docs/detectability.md`` shows them (``tests/test_detectability.py`` compares)."""
    lines = [
        "| fault type | kind | size unit | targets (one drawn per fault) | scenario fault | sweep grid "
        "| why this grid |",
        "|---|---|---|---|---|---|---|",
    ]
    for t in FAULT_TYPES:
        unit = t.unit if t.rule != "sigma" else f"σ of `{t.sigma_channel}`"
        targets = ", ".join(f"`{x}`" for x in t.targets)
        value = {
            "sigma": f"`{t.fault_kind.value}` ± size·σ",
            "gain_pct": f"`{t.fault_kind.value}` 1 ± size/100",
            "loss_pct": f"`{t.fault_kind.value}` 1 − size/100",
            "signed": f"`{t.fault_kind.value}` ± size",
            "magnitude": f"`{t.fault_kind.value}` size",
        }[t.rule]
        grid = ", ".join(f"{s:g}" for s in t.sizes)
        lines.append(f"| `{t.name}` | {t.kind} | {unit} | {targets} | {value} | {grid} | {t.grid_reason} |")
    lines += ["", "| kind | mean winds (m/s) | why |", "|---|---|---|"]
    lines += [f"| {kind} | {r.lo:g}–{r.hi:g} | {r.reason} |" for kind, r in WIND_RANGES.items()]
    return "\n".join(lines)
