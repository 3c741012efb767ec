"""VRS, FDS and ERS of dtdyn against FatigueDS and pyyeti on the same inputs, each difference
with its measured cause (docs/guide/test_specification.md prints this script's output).

    python benchmarks/fds_comparison.py          # about 20 s; needs FatigueDS and pyyeti
"""
import contextlib
import io

import numpy as np
from FatigueDS import Spectrum
from pyyeti import fdepsd, srs

from dtdyn.random_vibration import psd_table
from dtdyn.random_vibration._spectra import (extreme_response_spectrum, fatigue_damage_spectrum,
                                            vibration_response_spectrum)
from dtdyn.random_vibration._synthesis import random_time_history

TABLE = psd_table([(20, 0.01), (80, 0.04), (350, 0.04), (2000, 0.007)])
F_N = np.geomspace(30, 1500, 12)
T = 3600.0


def fatigueds_psd(freq, psd, b=6.0):
    s = Spectrum(freq_data=F_N.copy(), Q=10)
    s.set_random_load((psd, freq), T=T)
    s.get_ers()
    s.get_fds(k=b, C=1.0, p=1.0)
    return s


def staircase(freq, psd):
    df = freq[1] - freq[0]
    edges = np.r_[freq[0], freq[:-1] + df / 2, freq[-1]]

    def g(f):
        f = np.asarray(f, float)
        i = np.clip(np.searchsorted(edges, f, side="right") - 1, 0, psd.size - 1)
        return np.where((f >= edges[0]) & (f <= edges[-1]), psd[i], 0.0)
    g.freqs_hz = edges
    return g


def fmt(values):
    return "[" + ", ".join(f"{v:+.2e}" for v in np.ravel(values)) + "]"


def worst(a, b):
    return np.abs(np.asarray(a) / np.asarray(b) - 1).max()


def main():
    print("MIL-STD-810-like table (20, 0.01) (80, 0.04) (350, 0.04) (2000, 0.007) g^2/Hz; "
          "Q = 10; 12 natural frequencies 30 .. 1500 Hz; T = 3600 s; FDS slope 6")
    ers = extreme_response_spectrum(TABLE, F_N, 0.05, duration=T, peak="most_probable")
    fds = fatigue_damage_spectrum(TABLE, F_N, 0.05, slope=6.0, duration=T)
    print("\nFatigueDS 0.3.1 from a PSD (narrow-band FDS, most probable ERS):")
    print(f"  {'input to FatigueDS':44s} {'FDS max rel. diff':>18s} {'ERS max rel. diff':>18s}")
    for df in (2.0, 1.0, 0.5):
        freq = np.arange(20.0, 2000.0 + df / 2, df)
        s = fatigueds_psd(freq, TABLE(freq))
        print(f"  {f'the table sampled every {df:g} Hz':44s} {worst(s.fds, fds.values):18.2e} "
              f"{worst(s.ers, ers.values):18.2e}")
    freq = np.arange(20.0, 2000.5, 1.0)
    s = fatigueds_psd(freq, TABLE(freq))
    g = staircase(freq, TABLE(freq))
    ers_s = extreme_response_spectrum(g, F_N, 0.05, duration=T, peak="most_probable")
    fds_s = fatigue_damage_spectrum(g, F_N, 0.05, slope=6.0, duration=T)
    print(f"  {'same samples, dtdyn given FatigueDS staircase':44s} "
          f"{worst(s.fds, fds_s.values):18.2e} {worst(s.ers, ers_s.values):18.2e}")

    print("\npyyeti 1.4.7 srs.vrs (sum of the response PSD on its grid) against the VRS:")
    vrs = vibration_response_spectrum(TABLE, F_N, 0.05).values
    for df in (1.0, 0.1, 0.01):
        z = srs.vrs((TABLE.freqs_hz, TABLE.values), np.arange(20.0, 2000.0 + df / 2, df), 10.0,
                    False, Fn=F_N)
        print(f"  grid every {df:5g} Hz: max rel. diff {worst(z, vrs):.2e}")

    print("\nFrom a record (13.1 s synthesized from the table at dt = 1e-4 s), f_n = 60, "
          "250 Hz, slope 4, rainflow damage sum(n S^4):")
    dt = 1e-4
    x = random_time_history(TABLE, dt, 2**17, seed=3)
    f2 = np.array([60.0, 250.0])
    for resp, ours_r in (("absacce", "absolute_acceleration"), ("pvelo", "pseudo_velocity")):
        ours = fatigue_damage_spectrum(None, f2, 0.05, slope=4.0, ground_acceleration=x, dt=dt,
                                       response=ours_r).values
        d = {}
        for nb in (300, 3000, 30000):
            r = fdepsd.fdepsd(x, 1 / dt, f2, 10.0, resp=resp, detrend=False, winends=None,
                              hpfilter=None, nbins=nb, rolloff=None, parallel="no")
            d[nb] = r.di_sig["b=4"].values / ours - 1
            print(f"  pyyeti fdepsd ({resp:7s}), {nb:6d} amplitude bins: rel. diff "
                  f"{fmt(d[nb])}")
        extra = d[30000] - (d[3000] - d[30000]) / 9
        print(f"  extrapolated to infinitely many bins (Richardson, 1/nbins): "
              f"{fmt(extra)}")
    for step in (1e-4, 5e-5, 2.5e-5):
        xr = random_time_history(TABLE, step, int(round(13.1072 / step)), seed=3)
        ours = fatigue_damage_spectrum(None, f2, 0.05, slope=4.0, ground_acceleration=xr,
                                       dt=step).values
        s = Spectrum(freq_data=f2.copy(), Q=10)
        with contextlib.redirect_stderr(io.StringIO()), \
                contextlib.redirect_stdout(io.StringIO()):
            s.set_random_load((xr, step))
            s.get_fds(k=4.0, C=1.0, p=1.0)
        print(f"  FatigueDS convolution FDS, dt = {step:7.1e} s: rel. diff "
              f"{fmt(s.fds / ours - 1)}")

    print("\nFDS from the PSD against the rainflow FDS of one 105 s record (dt = 1e-4 s), "
          "slope 4:")
    x = random_time_history(TABLE, dt, 2**20, seed=11)
    Tx = (x.size - 1) * dt
    f3 = np.array([60.0, 150.0, 400.0])
    rec = fatigue_damage_spectrum(None, f3, 0.05, slope=4.0, ground_acceleration=x, dt=dt)
    segs = np.array([fatigue_damage_spectrum(None, f3, 0.05, slope=4.0, ground_acceleration=s,
                                             dt=dt, duration=Tx).values
                     for s in np.array_split(x, 16)])
    se = segs.std(axis=0, ddof=1) / np.sqrt(16) / rec.values
    for method in ("narrow_band", "dirlik"):
        p = fatigue_damage_spectrum(TABLE, f3, 0.05, slope=4.0, duration=Tx, method=method)
        print(f"  {method:12s} PSD / record - 1: {fmt(p.values / rec.values - 1)}"
              f"   (record's standard error {fmt(se)})")


if __name__ == "__main__":
    main()
