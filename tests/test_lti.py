"""wwcore.lti against scipy.signal, which the step code avoids importing for start-up time."""

import numpy as np
import pytest
from scipy.signal import butter, cont2discrete, lfilter_zi

from wwcore.lti import biquad_steady_state, butter2_lowpass, second_order_tf, zoh


def test_zoh_equals_cont2discrete():
    A = np.array([[0.0, 1.0], [-30.0, -4.0]])
    B = np.array([[0.0], [30.0]])
    phi, gamma = zoh(A, B, 0.01)
    ref = cont2discrete((A, B, np.eye(2), np.zeros((2, 1))), 0.01, method="zoh")
    assert np.allclose(phi, ref[0]) and np.allclose(gamma, ref[1])


@pytest.mark.parametrize("cutoff", [0.05, 0.3, 2.0, 20.0])
def test_butterworth_and_its_steady_state_equal_scipy(cutoff):
    b, a = butter2_lowpass(cutoff, 0.01)
    rb, ra = butter(2, cutoff, fs=100.0)
    assert np.allclose(b, rb, rtol=1e-10) and np.allclose(a, ra, rtol=1e-10)
    assert np.allclose(biquad_steady_state(b, a), lfilter_zi(rb, ra), rtol=1e-9)


def test_second_order_transfer_function_equals_cont2discrete():
    wn, zeta = 11.11, 0.6
    A = np.array([[0.0, 1.0], [-(wn**2), -2 * zeta * wn]])
    B = np.array([[0.0], [wn**2]])
    num, den = second_order_tf(*zoh(A, B, 0.01))
    ref_num, ref_den, _ = cont2discrete(([wn**2], [1.0, 2 * zeta * wn, wn**2]), 0.01, method="zoh")
    assert np.allclose(num, np.ravel(ref_num), atol=1e-12) and np.allclose(den, ref_den)


def test_quantiles_equal_scipy_stats():
    from scipy.stats import chi2, norm

    from wwcore.quantiles import chi2_isf, norm_isf

    for alpha in (1e-2, 1e-7):
        assert norm_isf(alpha) == pytest.approx(norm.isf(alpha), rel=1e-10)
        for dof in (1, 3, 12.5, 200):
            assert chi2_isf(alpha, dof) == pytest.approx(chi2.isf(alpha, dof), rel=1e-9)
