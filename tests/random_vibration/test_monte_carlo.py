"""Monte Carlo of random vibration through run_batch: a linear chain under synthesized
``kind = "psd"`` forces, 64 seeds, reduced per case (rms, peaks, Welch PSDs, rainflow damage)
and over the cases (`monte_carlo_summary`), against `chain_random_response` (the spectral
answer, an independent computation: no time integration), the sampling statistics of a
Gaussian mean square, and Dirlik's spectral damage; then the same scene with a cubic spring.

The time integration (average acceleration, the bilinear map s = (2/dt)(z-1)/(z+1)) answers a
sampled force exactly as the continuous model answers at the warped frequency
f' = tan(pi f dt) / (pi dt): its response PSD is |H(f')|^2 S_f(f). The Welch PSDs are compared
with that; its effect on the rms (computed below: under 3e-4 relative) is far inside the
Monte Carlo's interval, so the rms are compared with the continuous model's directly.
"""
import numpy as np
import pytest

import dtdyn as dd

distributed = pytest.importorskip("distributed")
pytest.importorskip("xarray")
pytest.importorskip("zarr")

from scipy import stats  # noqa: E402

from dtdyn.app import Damage, Rms, Welch, monte_carlo_summary  # noqa: E402
from dtdyn.random_vibration import (chain_random_response, psd_table,  # noqa: E402
                                    spectral_damage)

BREAKPOINTS = [[5.0, 1.0], [40.0, 1.0], [100.0, "-6 dB/oct"]]   # N^2/Hz
MASS, STIFFNESS, DAMPING = [1.0, 1.0, 1.0], [4e4, 4e4, 4e4], [60.0, 60.0, 60.0]
DT, DURATION, START = 2.5e-4, 21.0, 1.0       # s; slowest decay 1/(zeta omega) = 0.17 s
CASES, ROOT_SEED, CONFIDENCE = 64, 2024, 0.99
NPERSEG = 16384                               # 0.24 Hz bins; mode 1's half-power band: 1.9 Hz
SN = dd.SNCurve(slope=5.0, coefficient=1e12)  # amplitudes in "stress" = SCALE * x
SCALE = 2e8
SCENE = {"title": "a chain under a random force",
         "model": {"mass": MASS, "stiffness": STIFFNESS, "damping": DAMPING},
         "load": [{"dof": 2, "kind": "psd", "psd": BREAKPOINTS, "seed": 0}],
         "scheme": {"name": "average_acceleration"},
         "time": {"dt": DT, "duration": DURATION},
         "output": {"quantities": ["x", "a"]}}
REDUCE = [Rms(start=START), "peak", Welch(nperseg=NPERSEG, start=START),
          Damage(SN, scale=SCALE, start=START)]


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0", silence_logs=40) as cluster, \
            distributed.Client(cluster) as c:
        yield c


def monte_carlo(client, scene):
    ds = dd.run_batch(scene, vary=[{}] * CASES, seed=ROOT_SEED, client=client, reduce=REDUCE,
                      check=False, progress=False)
    assert list(ds["status"].values) == ["done"] * CASES, ds["message"].values
    return ds, monte_carlo_summary(ds, confidence=CONFIDENCE)


@pytest.fixture(scope="module")
def linear(client):
    return monte_carlo(client, SCENE)


def spectral(freqs_hz, psd=None, quantities=("x", "a")):
    return chain_random_response(MASS, STIFFNESS, DAMPING, psd_table(BREAKPOINTS) if psd is None
                                 else psd, freqs_hz, force_dofs=[2], quantities=quantities)


def warp(f):
    """The frequency at which the continuous model answers as the scheme does at f."""
    return np.tan(np.pi * f * DT) / (np.pi * DT)


def test_rms_within_the_reported_interval(linear):
    ds, s = linear
    table = psd_table(BREAKPOINTS)
    f = np.geomspace(5.0, 100.0, 4001)
    r = spectral(f)
    T = DURATION - START

    def scheme_psd(fp):   # the sampled force's PSD seen at the warped frequency f'
        fp = np.asarray(fp, float)
        return table(np.arctan(np.pi * fp * DT) / (np.pi * DT)) / (1 + (np.pi * fp * DT) ** 2)

    scheme = spectral(warp(f), scheme_psd)
    tq = stats.t.ppf(0.5 + CONFIDENCE / 2, CASES - 1)
    for q in ("x", "a"):
        low, high = s[f"rms_{q}_low"].values, s[f"rms_{q}_high"].values
        exact = r.rms[q]
        assert np.all((low < exact) & (exact < high)), (q, low / exact, high / exact)
        assert np.all((low < s[f"rms_{q}"].values) & (s[f"rms_{q}"].values < high))
        # the interval's width against the sampling error of a Gaussian mean square over T:
        # var = int G^2 df / T (Bendat & Piersol sec. 8.2.2), its mean over CASES cases; the
        # sample standard deviation of 64 values is within +-30 % of the true one (4 sigma)
        G = np.real(np.einsum("fii->fi", getattr(r, f"{q}_psd")))
        predicted = tq * np.sqrt(np.trapezoid(G**2, f, axis=0) / T / CASES)
        half = (high**2 - low**2) / 2
        assert np.all((0.7 < half / predicted) & (half / predicted < 1.3)), half / predicted
        # the scheme's own mean square differs from the continuous one by far less
        assert np.all(np.abs(scheme.m0[q] / r.m0[q] - 1) < 0.05 * half / r.m0[q])


def test_welch_psd_within_its_chi_square_interval(linear):
    ds, s = linear
    assert float(ds["welch_dof"][0]) == pytest.approx(Welch(NPERSEG).dof(int(20.0 / DT) + 1))
    fw = ds["freq_hz"].values
    band = (fw > 6.0) & (fw < 95.0)        # a few bins inside the table's band edges
    H2 = spectral(warp(fw[band]), 1.0)     # |H(f')|^2 per unit white force
    table = psd_table(BREAKPOINTS)
    for q in ("x", "a"):
        G = np.real(np.einsum("fii->fi", getattr(H2, f"{q}_psd"))) * table(fw[band])[:, None]
        low = s[f"welch_{q}_low"].values[band]
        high = s[f"welch_{q}_high"].values[band]
        inside = (low <= G) & (G <= high)
        # 99 % intervals: about 1 % of the bins outside (neighbours correlated: Hann)
        assert np.all(inside.mean(axis=0) > 0.97), (q, inside.mean(axis=0))
        # and no bin further than 5 standard deviations sqrt(2 / nu) of chi^2_nu / nu
        nu = s.attrs["welch_dof"]
        assert np.all(np.abs(s[f"welch_{q}"].values[band] / G - 1) < 5 * np.sqrt(2 / nu))


def test_damage_against_dirlik(linear):
    ds, s = linear
    f = np.geomspace(5.0, 100.0, 4001)
    r = spectral(f, quantities=("x",))
    for j in range(3):
        stress_psd = np.real(r.x_psd[:, j, j]) * SCALE**2
        dirlik = spectral_damage(stress_psd, f, SN, DURATION - START, method="dirlik")
        # Dirlik's formula is within about 10 % of rainflow counting on Gaussian records
        assert s["damage_x"].values[j] == pytest.approx(dirlik, rel=0.1)
        assert s["damage_x_low"].values[j] < s["damage_x"].values[j] < \
            s["damage_x_high"].values[j]
    per_case = ds["damage_x"].values
    assert np.all(per_case > 0) and per_case.shape == (CASES, 3)
    assert np.all(s["peak_x"].values > s["rms_x"].values * 3)     # Gaussian peaks over 20 s


def test_cubic_spring_runs_and_reports_its_interval(client, linear):
    _, lin = linear
    results = {}
    for k3 in (1e3, 8e10):      # N/m^3: k3 x0_rms^2 / k = 4e-9 and 0.3
        scene = {**SCENE, "element": [{"kind": "cubic", "i": 0, "k3": k3}]}
        ds, s = monte_carlo(client, scene)
        assert np.isfinite(ds["max_residual"].values).all()
        for name in ("rms_x", "rms_a", "damage_x", "welch_x"):
            # the Welch interval is left out (NaN) at 0 Hz and at the Nyquist frequency
            inner = slice(1, -1) if name.startswith("welch") else slice(None)
            for part in ("", "_low", "_high"):
                assert np.isfinite(s[name + part].values[inner]).all()
            assert np.all(s[name + "_low"].values[inner] < s[name + "_high"].values[inner])
        results[k3] = s
    tiny, hard = results[1e3], results[8e10]
    # the same seeds, a spring that does not act: the linear Monte Carlo's answer (the cubic
    # force k3 x^3 is 4e-9 of the linear spring's, far below the interval's width)
    for q in ("x", "a"):
        np.testing.assert_allclose(tiny[f"rms_{q}"].values, lin[f"rms_{q}"].values, rtol=1e-6)
    r = spectral(np.geomspace(5.0, 100.0, 2001))
    assert np.all((tiny["rms_x_low"].values < r.rms["x"]) & (r.rms["x"] < tiny["rms_x_high"]))
    # a hardening spring on mass 0 lowers its displacement: the intervals do not overlap
    assert hard["rms_x_high"].values[0] < lin["rms_x_low"].values[0]


def test_store_summary_and_resume(client, tmp_path):
    """Welch's frequencies and welch_dof go through the Zarr store; the summary of the store
    equals that of the in-memory result; a resumed store with a Welch runs its pending cases
    on the store's frequencies."""
    short = {**SCENE, "time": {"dt": 1e-3, "duration": 3.0}}
    reduce = [Rms(start=1.0), Welch(nperseg=256, start=1.0), Damage(SN, scale=SCALE)]
    kwargs = {"vary": [{}] * 6, "seed": 5, "client": client, "reduce": reduce, "check": False,
              "progress": False}
    memory = dd.run_batch(short, **kwargs)
    path = tmp_path / "mc.zarr"
    stored = dd.run_batch(short, out=path, **kwargs)
    np.testing.assert_array_equal(stored["freq_hz"].values, np.fft.rfftfreq(256, 1e-3))
    a, b = monte_carlo_summary(memory), monte_carlo_summary(path)
    for name in a.data_vars:
        np.testing.assert_array_equal(a[name].values, b[name].values)
    assert b.attrs["welch_dof"] == pytest.approx(6 * Welch(256).dof(2001))
    import zarr   # mark two cases pending, as a batch killed before finishing them leaves them
    status = zarr.open_array(str(path / "status"), mode="r+")
    status[4:] = "pending"
    again = dd.run_batch(short, out=path, resume=True, **kwargs)
    assert json_summary(again)["ran"] == 2
    np.testing.assert_array_equal(again["welch_x"].values, memory["welch_x"].values)


def json_summary(ds):
    import json
    return json.loads(ds.attrs["dtdyn_batch"])["summary"]


def test_reducer_errors():
    with pytest.raises(ValueError, match="reduce = 'damage': the damage needs an S-N curve"):
        dd.run_batch(SCENE, reduce="rms,damage")
    with pytest.raises(ValueError, match="Damage.sn_curve = None: give a dtdyn.SNCurve"):
        Damage()
    with pytest.raises(ValueError, match=r"Welch.nperseg = 2: must be an integer >= 4"):
        Welch(nperseg=2)
    with pytest.raises(ValueError, match=r"Rms.start = -1.0: must be a time >= 0"):
        Rms(start=-1.0)
    with pytest.raises(ValueError, match="confidence = 1.5"):
        monte_carlo_summary(None, confidence=1.5)
