"""Harmonic balance on a beam with a cubic spring and a gap against long time-domain runs
(the model of benchmarks/harmonic_balance_beam.py on 60 elements)."""
import warnings

import numpy as np

import dtdyn as dd

E, I, RHO_A, L = 2.1e11, 8e-6, 20.0, 3.0  # noqa: E741
N = 60
F_HZ = 18.5                     # near the first resonance (18.0 Hz): the gap is in contact


def _model():
    w1, w2 = (b ** 2 * np.sqrt(E * I / (RHO_A * L ** 4)) for b in (1.8751040687, 4.6940911330))
    beta = 2 * 0.05 / (w1 + w2)                     # 5 % in modes 1 and 2
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=N, rayleigh=(beta * w1 * w2, beta))
    tip, mid = beam.dof(f"w{N}"), beam.dof(f"w{N // 2}")
    elements = [dd.Cubic(tip, k3=7.5e8), dd.Gap(mid, gap=1e-3, stiffness=1e5)]
    return beam, elements, [tip, mid]


def _time_domain(steps):
    """max |x| of tip and mid-span over the last period of a 3 s run from rest (the force ramped
    in over 0.5 s), dt = T / steps, by the period's Fourier series on a 16x finer grid."""
    beam, elements, dofs = _model()
    dt = 1.0 / F_HZ / steps
    t = np.arange(int(round(3.0 * F_HZ)) * steps + 1) * dt
    ramp = np.where(t < 0.5, 0.5 * (1 - np.cos(np.pi * t / 0.5)), 1.0)
    r = dd.nonlinear_beam_response(beam, 100.0 * ramp * np.cos(2 * np.pi * F_HZ * t), dt,
                                   force_dofs=[dofs[0]], elements=elements, outputs=dofs,
                                   quantities=("x",), scheme="average_acceleration")
    periods = [r.x[-steps:], r.x[-2 * steps:-steps]]
    amp = [np.abs(np.fft.irfft(np.fft.rfft(p, axis=0), n=16 * steps, axis=0)).max(axis=0) * 16
           for p in periods]
    return amp[0], abs(amp[0] / amp[1] - 1).max()


def _harmonic_balance(receptance, harmonics=20):
    beam, elements, dofs = _model()
    with warnings.catch_warnings():        # one point at F_HZ: the curve stops at max_points
        warnings.filterwarnings("ignore", "harmonic_balance stopped after max_points")
        r = dd.harmonic_balance(beam, elements=elements, force_dofs=[dofs[0]], force=[100.0],
                                outputs=dofs, freqs_hz=(F_HZ, F_HZ * (1 + 1e-6)), max_points=2,
                                harmonics=harmonics, stability=False, receptance=receptance,
                                convergence_points=0)
    assert r.info["receptance"] == receptance
    return r.x_max[0]


def test_gap_and_cubic_on_a_beam_equal_the_time_domain():
    x1, transient1 = _time_domain(512)
    x2, transient2 = _time_domain(1024)
    assert max(transient1, transient2) < 1e-6          # steady: the transient has died out
    # Newmark's average acceleration is second order: halving dt leaves (x2 - x1) / 3 as the
    # error of x2 (about 1e-5 here), which Richardson's extrapolation removes
    assert np.abs(x2 / x1 - 1).max() < 1e-4
    x_td = x2 + (x2 - x1) / 3
    reduced = _harmonic_balance("reduced")
    banded = _harmonic_balance("banded")
    # both receptances solve the same model (measured: 6e-9, the reduced one's check at 1e-8)
    assert np.abs(reduced / banded - 1).max() <= 1e-7
    # H = 20 against 40: the gap's kink converges slowly in the harmonics (6e-6 here); with what
    # the extrapolation leaves of the time domain's error, 2e-5 in all (measured: 9e-6)
    truncation = np.abs(reduced / _harmonic_balance("reduced", 40) - 1).max()
    assert truncation < 1e-5
    assert np.abs(reduced / x_td - 1).max() <= 2e-5
    # and the gap is in contact (the mid-span beyond its clearance): the test sees its law
    assert reduced[1] > 1e-3
