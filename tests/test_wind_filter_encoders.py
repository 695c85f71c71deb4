"""The wind filter of the observers on noisier speed channels than observer 4's (``wind_recovery.torque_cutoffs``):
after a double fault that leaves one encoder, or both encoders faulty in region 1 (observer 5, the rotor-speed
sensors), the torque estimate the wind is inverted from stands to what the healthy sensors allow (the steady-state
Kalman filter of the rigid drive train on them, ``scipy.linalg.solve_discrete_are``) as the fault-free estimate stands
to what all sensors allow (docs/turbine.md, "A double fault that leaves one encoder", "Both encoders in region 1")."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from plant_sim.turbine import TurbineBatch
from service.turbine.bank import GENERATOR, ObserverBank, estimate_observers
from service.turbine.builtin import UIOBankEstimator
from service.turbine.interfaces import POWER_SPEED_MIN_TORQUE, TurbineContext
from service.turbine.supervisor import TurbineSupervisor
from service.turbine.wind_recovery import SETTLE_ITERATIONS, WindRecovery, speed_noise_variance, torque_cutoffs
from wwcore import aero
from wwcore.channels import DIAGNOSIS_TARGETS, SPEED_SENSORS, TARGET_INDEX
from wwcore.scenario import parse_scenario
from wwcore.turbine_params import BENCHMARK as P

DESIGN = TurbineContext(P, 1).bank_design
SIGMA_G = 0.05  # rad/s, a generator-speed sensor's noise (wwcore.channels)
SIGMA_R = 0.004 * 2.0 * np.pi  # rad/s, a rotor-speed sensor's
J_EQ = P.J_r / P.N_g + P.N_g * P.J_g / P.eta_dt  # the rigid drive train's inertia on the generator side, kg m²
DAMPING = P.N_g * P.B_g / P.eta_dt + P.B_r / P.N_g  # its friction, N m s/rad
BIT = {s: 1 << i for i, s in enumerate(SPEED_SENSORS)}


def _rigid_model() -> tuple[np.ndarray, np.ndarray]:
    """[ω_g, τ_r] of the rigid drive train with τ_g = 0, J_eq (ω[n] − ω[n−1])/Ts + D ω[n] = τ_r[n] (the equation
    ``WindRecovery`` inverts for a rigid observer) and τ_r[n] = τ_r[n−1] + w[n]: x[n] = A x[n−1] + G w[n]."""
    inertia = J_EQ / P.dt
    a, b = inertia / (inertia + DAMPING), 1.0 / (inertia + DAMPING)
    return np.array([[a, b], [0.0, 1.0]]), np.array([b, 1.0])


def kalman_torque_std(q: float, r: float) -> float:
    """σ of τ̂_r[n] (N m) of the steady-state Kalman filter of ``_rigid_model`` with random-walk variance q per tick,
    measuring ω_g with variance r: the filtered covariance from the Riccati equation's predicted one."""
    A, G = _rigid_model()
    C = np.array([[1.0, 0.0]])
    predicted = solve_discrete_are(A.T, C.T, q * np.outer(G, G), np.array([[r]]))
    gain = predicted @ C.T / (C @ predicted @ C.T + r)
    return float(np.sqrt((predicted - gain @ C @ predicted)[1, 1]))


def test_one_encoder_filter_is_the_kalman_bandwidth_law():
    """The cutoff for one encoder of two is the design's × 2^(−1/4), the optimal filter's scaling with the sensor
    variance; the Riccati equation gives the optimum's error on one encoder as 2^(1/8) × on two."""
    cutoffs = torque_cutoffs(DESIGN, 0.3)
    four = DESIGN.index(frozenset({"omega_r_m1", "omega_r_m2"}))
    assert cutoffs[four] == 0.3
    for j in DESIGN.single_generator:
        assert cutoffs[j] == pytest.approx(0.3 * 2.0**-0.25, rel=1e-12)
    five = DESIGN.index(frozenset(GENERATOR))
    others = [j for j in range(len(DESIGN.names)) if j not in (*DESIGN.single_generator, five)]
    assert np.all(cutoffs[others] == 0.3)
    q = 1e4
    ratio = kalman_torque_std(q, SIGMA_G**2) / kalman_torque_std(q, SIGMA_G**2 / 2)
    assert ratio == pytest.approx(2.0**0.125, rel=2e-3)


def kalman_bandwidth_hz(q: float, r: float) -> float:
    """Bandwidth (Hz) of the steady-state Kalman filter of ``_rigid_model`` (random-walk variance q per tick, ω_g
    measured with variance r): the natural frequency of its error dynamics' poles, A − A K C."""
    A, G = _rigid_model()
    C = np.array([[1.0, 0.0]])
    predicted = solve_discrete_are(A.T, C.T, q * np.outer(G, G), np.array([[r]]))
    gain = predicted @ C.T / (C @ predicted @ C.T + r)
    poles = np.linalg.eigvals(A - A @ gain @ C)
    return float(np.abs(np.log(poles)).max() / (2.0 * np.pi * P.dt))


def test_rotor_speed_filter_is_the_riccati_bandwidth():
    """Observer 5 (the rotor-speed sensors, r_5 = N_g² σ_r²/2 on the generator side, 2 280 × observer 4's σ_g²/2)
    filters its torque at the design's cutoff × the ratio of the two sensor sets' Kalman bandwidths (Riccati), for
    the random walk that puts observer 4's at the design's 0.3 Hz: 0.0434 Hz. The optimum's torque error on the
    rotor-speed sensors is then 2 280^(1/8) = 2.63 × on the encoders: the floor of a double generator-speed fault
    where the torque estimate's noise is its error (region 1). The 5-pe designs keep the design's cutoff."""
    r4, r5 = SIGMA_G**2 / 2.0, (P.N_g * SIGMA_R) ** 2 / 2.0
    five = DESIGN.index(frozenset(GENERATOR))
    assert speed_noise_variance(DESIGN.observers[five], DESIGN.gear_ratio) == pytest.approx(r5, rel=1e-12)
    four = DESIGN.index(frozenset({"omega_r_m1", "omega_r_m2"}))
    assert speed_noise_variance(DESIGN.observers[four], DESIGN.gear_ratio) == pytest.approx(r4, rel=1e-12)
    q = (2.0 * np.pi * 0.3) ** 4 * J_EQ**2 * r4 * P.dt**2  # the closed form's random walk for 0.3 Hz on r4
    assert kalman_bandwidth_hz(q, r4) == pytest.approx(0.3, rel=1e-4)
    cutoffs = torque_cutoffs(DESIGN, 0.3)
    assert cutoffs[five] == pytest.approx(0.3 * kalman_bandwidth_hz(q, r5) / kalman_bandwidth_hz(q, r4), rel=1e-6)
    assert cutoffs[five] == pytest.approx(0.0434, abs=5e-5)
    assert kalman_torque_std(q, r5) / kalman_torque_std(q, r4) == pytest.approx((r5 / r4) ** 0.125, rel=0.01)
    assert np.all(cutoffs[list(DESIGN.power_speed)] == 0.3)


def test_region1_estimate_with_both_encoders_flagged_is_observer_5():
    """Below the power-speed channel's threshold that channel is the rotor-speed sensors' mean, so with both
    generator-speed sensors distrusted the estimate comes from observer 5 (and its filter) instead of a 5-pe design,
    in either zone; above it, and with ``power_speed = false``, nothing changes (the selection's region-1 band)."""
    five = DESIGN.index(frozenset(GENERATOR))
    pe15, pe_r3 = DESIGN.power_speed[0], DESIGN.power_speed[-1]
    faulty = np.zeros((4, len(DIAGNOSIS_TARGETS)), dtype=bool)
    faulty[:, [TARGET_INDEX[s] for s in GENERATOR]] = True
    faulty[2, TARGET_INDEX[GENERATOR[0]]] = False  # one encoder left: observer 4 on it
    zone = np.array([0, 0, 0, 1])
    threshold = POWER_SPEED_MIN_TORQUE * P.rated_torque
    torque = np.array([0.5, 1.5, 0.5, 1.5]) * threshold
    for backend in ("numpy", "numba"):
        estimator = UIOBankEstimator(context=TurbineContext(P, 4, backend=backend))
        one = DESIGN.single_generator[GENERATOR.index(GENERATOR[1])]
        assert estimator.select(faulty, torque, zone)[1].tolist() == [five, pe15, one, pe_r3]
        low = np.full(4, 0.5 * threshold)
        assert estimator.select(faulty, low, zone)[1].tolist() == [five, five, one, five]
        published = UIOBankEstimator(context=TurbineContext(P, 4, backend=backend), options={"power_speed": False})
        assert published.select(faulty, torque, zone)[1].tolist() == [five, five, one, five]


def _run(q: float, ticks: int, rows: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A rigid drive train turned by a random-walk torque, seen by ``rows`` fault-free turbines and ``rows`` with
    ω_r,m2 and ω_g,m1 offset (the same torque and the same ω_g,m2 noise). Returns the true τ_r (ticks, rows) and
    the filtered τ̂_r of the observer the estimate comes from in each half (fault-free: all sensors healthy;
    faulty: ω_r,m2 and ω_g,m1 flagged since the first tick), (ticks, rows) each."""
    rng = np.random.default_rng(seed)
    A, G = _rigid_model()
    omega0 = 150.0
    x = np.tile([omega0, DAMPING * omega0], (rows, 1))  # at rest
    n = 2 * rows
    choice = estimate_observers(DESIGN)
    healthy_column = choice[0]
    faulty_column = choice[BIT["omega_r_m2"] | BIT["omega_g_m1"]]
    used = set(DESIGN.observers[faulty_column].sensors)
    assert used <= {"omega_r_m1", "omega_g_m2"} and used & set(GENERATOR)  # only the healthy sensors
    offsets = np.zeros(4)
    offsets[SPEED_SENSORS.index("omega_r_m2")] = 10 * SIGMA_R
    offsets[SPEED_SENSORS.index("omega_g_m1")] = -15 * SIGMA_G

    def read(x: np.ndarray) -> np.ndarray:
        true = np.column_stack([x[:, 0] / P.N_g, x[:, 0] / P.N_g, x[:, 0], x[:, 0]])
        noise = rng.standard_normal((rows, 4)) * [SIGMA_R, SIGMA_R, SIGMA_G, SIGMA_G]
        other = rng.standard_normal(rows) * SIGMA_G  # the faulty half's own ω_g,m1 noise
        faulty = true + noise + offsets
        faulty[:, SPEED_SENSORS.index("omega_g_m1")] += other - noise[:, SPEED_SENSORS.index("omega_g_m1")]
        # the bank's fifth input, the power-speed channel (``interfaces.power_speed``), ~0.6 % of ω_g; no
        # observer on a generator-speed sensor reads it
        power_speed = x[:, 0] * (1.0 + 0.006 * rng.standard_normal(rows))
        return np.column_stack([np.vstack([true + noise, faulty]), np.tile(power_speed, 2)])

    y = read(x)
    bank = ObserverBank(DESIGN, n)
    start = np.column_stack([np.tile(x[:, 0] / P.N_g, 2), np.tile(x[:, 0], 2), np.zeros(n), np.zeros(n)])
    bank.initialise(start, y)
    recovery = WindRecovery(P, DESIGN, n, wind_cutoff_hz=0.3, speed_cutoff_hz=2.0)
    recovery.start(bank.x_hat, np.zeros(n), np.tile(x[:, 1], 2))
    no_pitch = np.zeros((n, 3))
    truth, fault_free, faulty = (np.empty((ticks, rows)) for _ in range(3))
    for k in range(ticks):
        x = x @ A.T + np.outer(rng.standard_normal(rows) * np.sqrt(q), G)
        y = read(x)
        bank.step(y, np.zeros(n))
        recovery.step(bank.x_hat, np.zeros(n), no_pitch, no_pitch, None, None)
        truth[k] = x[:, 1]
        fault_free[k] = recovery.filtered[:rows, healthy_column]
        faulty[k] = recovery.filtered[rows:, faulty_column]
    return truth, fault_free, faulty


def test_double_fault_estimate_stands_to_the_healthy_sensors_optimum_as_the_fault_free_one_does():
    """A random-walk torque slow enough that the design's 0.3 Hz is noise-bound (the optimal bandwidth for two
    encoders ≈ 0.1 Hz, as at 4–5 m/s where a torque error moves the wind estimate most): with the cutoff kept, the
    one-encoder estimate's error is √2-like × the fault-free one's (1.4 here); scaled by 2^(−1/4), both are the
    same multiple of their Kalman optimum, and the ratio is the optimum's 2^(1/8) = 1.09, under the 1.1 target."""
    bandwidth = 2.0 * np.pi * 0.1  # rad/s, the Kalman filter's on two encoders: (q / (J_eq² r Ts²))^(1/4)
    q = bandwidth**4 * J_EQ**2 * (SIGMA_G**2 / 2) * P.dt**2
    truth, fault_free, faulty = _run(q, ticks=30_000, rows=24, seed=7)
    settle = 2_000  # 20 s, far beyond the filters' and the random walk's start
    error_fault_free = np.sqrt(np.mean((fault_free[settle:] - truth[settle:]) ** 2))
    error_faulty = np.sqrt(np.mean((faulty[settle:] - truth[settle:]) ** 2))
    optimum_two, optimum_one = kalman_torque_std(q, SIGMA_G**2 / 2), kalman_torque_std(q, SIGMA_G**2)
    assert error_fault_free > optimum_two and error_faulty > optimum_one  # nothing beats the optimum
    assert error_faulty / optimum_one == pytest.approx(error_fault_free / optimum_two, rel=0.03)
    assert error_faulty / error_fault_free < 1.1


def test_take_over_between_different_cutoffs_starts_from_the_source_output():
    """At rest, 4 taking over 4-g1's filters (``WindRecovery.transfer``, after a flagged generator-speed sensor is
    trusted again) goes on at the same output: the target's rest state, not the source's state under other
    coefficients (17 N m off at 670 kN m here)."""
    x = np.array([[150.0 / P.N_g, 150.0, 0.0, 0.0]])
    tau_r = DAMPING * 150.0
    y = np.array([[150.0 / P.N_g, 150.0 / P.N_g, 150.0, 150.0, 150.0]])  # the speeds and the power-speed channel
    bank = ObserverBank(DESIGN, 1)
    bank.initialise(x, y)
    recovery = WindRecovery(P, DESIGN, 1, wind_cutoff_hz=0.3, speed_cutoff_hz=2.0)
    recovery.start(bank.x_hat, np.zeros(1), np.array([tau_r]))
    no_pitch = np.zeros((1, 3))
    for _ in range(50):
        bank.step(y, np.zeros(1))
        recovery.step(bank.x_hat, np.zeros(1), no_pitch, no_pitch, None, None)
    four = DESIGN.index(frozenset({"omega_r_m1", "omega_r_m2"}))
    source = DESIGN.single_generator[0]
    rows, target, from_ = np.array([0]), np.array([four]), np.array([source])
    bank.restart(rows, target, from_)
    recovery.transfer(rows, target, from_, DESIGN, bank.x_hat)
    for _ in range(300):
        bank.step(y, np.zeros(1))
        recovery.step(bank.x_hat, np.zeros(1), no_pitch, no_pitch, None, None)
        assert recovery.filtered[0, four] == pytest.approx(tau_r, rel=1e-9)


AT_4_MS = """
name = "region-1"
duration_s = 40.0
[plant]
kind = "turbine"
[wind]
mean = [[0.0, 4.0]]
turbulence_intensity = 0.12
"""


def _run_to_an_inversion(plant: TurbineBatch, supervisor: TurbineSupervisor, ticks: int) -> None:
    """Step the plant and its supervisor ``ticks`` ticks, then on up to the tick before the estimator's next wind
    inversion (``wind_every``), so that the next ``estimator.step`` inverts."""
    estimator, refs, k = supervisor.estimator, None, 0
    while k < ticks or estimator.ticks % estimator.wind_every:
        frame = plant.measure()
        plant.control(refs)
        refs = supervisor.step(frame)
        plant.advance()
        k += 1


def test_a_change_of_observer_inverts_the_new_torque_afresh():
    """The wind is inverted every 0.2 s by 3 iterations from the previous estimate, which suffice where the torque
    moved little since. A change of observer breaks that: the guess belongs to the old observer's torque, which a
    fault not yet caught may have taken far off (a −2σ/s encoder drift took the estimate 1.3 m/s low in 2 s at
    4 m/s, and 3 iterations from there, in region 1's stall, went 2.8 m/s low). The estimate is then the new
    observer's own root (``WindRecovery.wind``'s ``moved``), whatever the guess; an unmoved estimate is untouched."""
    scenario = parse_scenario(tomllib.loads(AT_4_MS))
    plant = TurbineBatch(scenario.plant, scenario.wind, [], seed=5, runs=[0, 1])
    supervisor = TurbineSupervisor(plant.n)
    estimator = supervisor.estimator
    _run_to_an_inversion(plant, supervisor, 3000)  # 30 s: observer 5's start (its filters) has died out
    fault_free = supervisor.estimates.wind.copy()
    estimator._winds[0, 0] = 0.3 * fault_free[0]  # row 0: an estimate a fault took far off before it was suspected
    frame = plant.measure()
    faulty = np.zeros((plant.n, len(DIAGNOSIS_TARGETS)), dtype=bool)
    faulty[0, [TARGET_INDEX[s] for s in GENERATOR]] = True  # row 0: both encoders suspected; row 1 unchanged
    estimates = estimator.step(frame, faulty)
    five = DESIGN.index(frozenset(GENERATOR))
    assert estimates.selected[0] == five  # region 1: observer 5 (the selection's region-1 band)
    recovery = estimator.recovery
    column = np.array([five, estimates.selected[1]])
    args = (
        recovery.filtered[[0, 1], column],
        recovery.omega_r[[0, 1], column],
        recovery.pitch_filtered,
    )
    root = aero.wind_from_torque(*args, fault_free, P, iterations=60)
    warm = aero.wind_from_torque(*args, 0.3 * fault_free, P, iterations=3)  # row 0's, on main
    assert abs(warm[0] - root[0]) > 0.2  # the warm start alone: still far from the new observer's root
    assert estimates.wind[0] == pytest.approx(root[0], rel=1e-9)
    unmoved = aero.wind_from_torque(*(a[1] for a in args), fault_free[1], P, iterations=3)
    assert estimates.wind[1] == pytest.approx(unmoved, rel=1e-12)  # the warm start's 3 iterations
    assert np.log(aero.WIND_MAX / aero.WIND_MIN) / np.log(1.0 + aero._AWAY_STEP) <= SETTLE_ITERATIONS


def test_a_fresh_inversion_below_cut_in_from_a_bad_warm_start_returns_the_stalled_root():
    """Region 1 (below cut-in) runs on τ(v)'s stalled branch (λ ≈ 2 at 4 m/s; the hump is at λ ≈ 3.5–4.7). With
    negative pitch a torque between the trough's and the hump's levels has three roots; at the 4 m/s rotor speed,
    β = −1.5 deg and a 3 m/s wind's torque they are 1.38, 2.28 and 3 m/s. A fresh inversion (a change of observer)
    from an estimate a fault took low (1.2 m/s, below the hump) went up the unstalled branch to 1.38 m/s; on a
    region-1 row (``stalled``) it returns the stalled root, 3 m/s. Off region 1 and where τ(v) has one root the
    result is the guess's root, unchanged to the last bit."""
    omega, beta, truth = 0.137, -1.5, 3.0
    grid = np.linspace(1.0, 8.0, 7001)
    excess = aero.rotor_torque(grid, omega, beta, P) - aero.rotor_torque(truth, omega, beta, P)
    assert np.count_nonzero(np.diff(excess > 0.0)) == 3  # three roots in [1, 8] m/s
    five = DESIGN.index(frozenset(GENERATOR))
    recovery = WindRecovery(P, DESIGN, 3, wind_cutoff_hz=0.3, speed_cutoff_hz=2.0)
    filtered = np.zeros((3, 3 * len(DESIGN.names) + 1))
    torque = np.array([aero.rotor_torque(truth, omega, beta, P), aero.rotor_torque(truth, omega, beta, P), 6.0e4])
    filtered[:, five] = torque
    filtered[:, recovery.speed_starts[0] + five] = omega
    filtered[:, -1] = [beta, beta, 0.0]  # row 2: β = 0, one root (the stall plateau only flattens τ(v))
    recovery._filtered = filtered
    columns = np.full((1, 3), five)
    guess = np.full((1, 3), 1.2)
    moved = np.ones((1, 3), dtype=bool)
    main = recovery.wind(columns, guess, moved)  # no row on the stalled branch: the guess's root
    assert main[0, 0] == pytest.approx(1.381, abs=2e-3)
    stalled = np.array([True, False, True])
    v = recovery.wind(columns, guess, moved, stalled)
    assert v[0, 0] == pytest.approx(truth, rel=1e-9)
    assert v[0, 1] == main[0, 1] and v[0, 2] == main[0, 2]  # off region 1; one root
    # unmoved estimates are untouched whatever ``stalled`` says
    np.testing.assert_array_equal(recovery.wind(columns, guess, ~moved, stalled), recovery.wind(columns, guess, ~moved))


def test_region_1_rows_invert_on_the_stalled_branch():
    """The estimator tells the inversion which rows are in region 1 (the torque reference below
    ``POWER_SPEED_MIN_TORQUE`` × rated, the selection's band): at 4 m/s all of them, at 7 m/s none."""
    seen = []
    for wind in (4.0, 7.0):
        scenario = parse_scenario(tomllib.loads(AT_4_MS.replace("4.0", str(wind))))
        plant = TurbineBatch(scenario.plant, scenario.wind, [], seed=5, runs=[0, 1])
        supervisor = TurbineSupervisor(plant.n)
        recovery = supervisor.estimator.recovery
        inversion = recovery.wind

        def wind_seen(columns, v_guess, moved=None, stalled=None, inversion=inversion, wind=wind):
            seen.append((wind, stalled.copy()))
            return inversion(columns, v_guess, moved, stalled)

        recovery.wind = wind_seen
        refs = None
        for _ in range(300):
            frame = plant.measure()
            plant.control(refs)
            refs = supervisor.step(frame)
            plant.advance()
    assert all(s.all() for w, s in seen if w == 4.0) and not any(s.any() for w, s in seen[-5:] if w == 7.0)


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_the_wind_estimate_holds_while_no_observer_leaves_out_the_distrusted_sensors(backend):
    """Three speed sensors distrusted (two flagged and a third suspected, as on the benchmark's F5 window when an
    isolation of a further fault briefly suspected the last encoder): no observer leaves them all out (``select``
    −1). The estimate then holds its last value, where inverting column 0 (the all-sensor observer, which reads the
    distrusted sensors) took one run of `benchmark-turbine --seed 83504` from 9.8 to 23.8 m/s; the next inversion on
    an observer starts from the held value. The other row is untouched."""
    scenario = parse_scenario(tomllib.loads(AT_4_MS.replace("4.0", "9.0")))
    plant = TurbineBatch(scenario.plant, scenario.wind, [], seed=5, runs=[0, 1])
    supervisor = TurbineSupervisor(plant.n, backend=backend)
    estimator = supervisor.estimator
    _run_to_an_inversion(plant, supervisor, 1000)
    before = supervisor.estimates.wind.copy()
    faulty = np.zeros((plant.n, len(DIAGNOSIS_TARGETS)), dtype=bool)
    faulty[0, [TARGET_INDEX[s] for s in ("omega_r_m2", "omega_g_m1", "omega_g_m2")]] = True
    estimates = estimator.step(plant.measure(), faulty)
    assert estimates.selected[0] == -1 and not estimates.valid[0]
    assert estimates.wind[0] == before[0]  # held, not column 0's inversion
    assert estimates.selected[1] >= 0 and estimates.wind[1] != before[1]  # row 1 inverted as always
