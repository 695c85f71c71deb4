"""The TS model (6)–(15): exact inside the envelope, convex memberships, bounds that cover the operation."""

from __future__ import annotations

import numpy as np

from service.hydro.ts_model import build_ts_model, memberships, premise_bounds, premises, system_matrix
from wwcore.hydro_model import aero_torque, derivative, equilibrium
from wwcore.hydro_params import NOMINAL as P


def _random_states(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    env = P.envelope
    x = np.column_stack(
        [
            rng.uniform(env.omega_r_min, env.omega_r_max, n),
            rng.uniform(env.omega_g_min, env.omega_g_max, n),
            rng.uniform(-1e7, 3.5e7, n),
            rng.uniform(0.0, 4e4, n),
            rng.uniform(env.x_p_min, env.x_p_max, n),
            rng.uniform(env.x_M_min, env.x_M_max, n),
        ]
    )
    u = np.column_stack([rng.uniform(0, 1.5, n), rng.uniform(0, 1.5, n), rng.uniform(0, 4e4, n)])
    v = rng.uniform(env.v_min, env.v_max, n)
    return x, u, v


def test_ts_model_reproduces_the_nonlinear_derivative_inside_the_envelope():
    ts = build_ts_model(P)
    x, u, v = _random_states(np.random.default_rng(0), 2000)
    T_r = aero_torque(x[:, 0], v, P)
    z = premises(x, T_r)
    assert ts.bounds.inside(z).all()
    exact = derivative(x, u, T_r, P)
    scale = np.array([1.0, 100.0, 3e7, 4e4, 1.0, 1.0])
    assert np.abs((ts.derivative(x, u, z) - exact) / scale).max() < 1e-9


def test_memberships_are_convex_and_rebuild_the_premises():
    ts = build_ts_model(P)
    rng = np.random.default_rng(1)
    z = rng.uniform(ts.bounds.lo, ts.bounds.hi, (500, 3))
    h = memberships(z, ts.bounds)
    assert h.shape == (500, 8) and (h >= 0).all()
    assert np.allclose(h.sum(axis=1), 1.0)
    # (9): Σ h_i f_j(vertex i) = f_j
    assert np.allclose(h @ ts.vertex_premises(), z)
    # and the blended vertex matrices are A(z) of (7)
    A = np.einsum("k,kij->ij", h[0], ts.A)
    assert np.allclose(A, system_matrix(z[0], P), rtol=1e-10, atol=1e-12)


def test_bounds_cover_the_partial_load_operation():
    b = premise_bounds(P)
    eq = equilibrium(np.linspace(4.0, 11.0, 15), P)
    z = premises(eq.x, aero_torque(eq.x[:, 0], np.linspace(4.0, 11.0, 15), P))
    assert b.inside(z).all()
    assert b.lo[0] < 0.0 < b.hi[0]  # the aero torque can turn negative at high λ inside the envelope
