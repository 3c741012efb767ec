"""
Shock response spectrum of a half-sine
======================================

The maximax shock response spectrum (SRS) of a 1 ms, 100 g half-sine pulse sampled at 100 kHz,
5 % damping, with the exact peaks between samples, against the peaks picked at the samples.
"""
import matplotlib.pyplot as plt
import numpy as np

import dtdyn as dd

dt = 1e-5
t = np.arange(2001) * dt
ag = np.where(t < 1e-3, 100.0 * np.sin(np.pi * t / 1e-3), 0.0)          # g
freqs_hz = np.geomspace(10.0, 10e3, 80)
exact = dd.shock_response_spectrum(ag, dt, freqs_hz, damping_ratio=0.05, exact_peaks=True)
sampled = dd.shock_response_spectrum(ag, dt, freqs_hz, damping_ratio=0.05)
i = exact.maximax.argmax()
print(f"peak {exact.maximax[i]:.1f} g at {freqs_hz[i]:.0f} Hz; peaks picked at the samples "
      f"differ by up to {np.abs(sampled.maximax / exact.maximax - 1).max():.1e}")

fig, ax = plt.subplots(figsize=(7, 4))
ax.loglog(freqs_hz, exact.maximax, label="maximax, exact peaks")
ax.loglog(freqs_hz, sampled.maximax, "--", label="maximax, sampled peaks")
ax.set_xlabel("natural frequency [Hz]")
ax.set_ylabel("peak absolute acceleration [g]")
ax.grid(True, which="both", lw=0.3)
ax.legend()
fig.tight_layout()
plt.show()
