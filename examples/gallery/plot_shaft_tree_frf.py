"""
Frequency response of a geared shaft tree
=========================================

A drive line of three disks, clamped at its left end, whose middle disk drives two branches
through gears (ratios 2 and -3.5). `shaft_frequency_response` gives the receptance of each
branch's last disk to a torque on the first disk by the tree's sweep; the natural frequencies
from `shaft_frequencies` sit at its peaks.
"""
import matplotlib.pyplot as plt
import numpy as np

import dtdyn as dd

branches = [dd.Branch(1, [0.5, 0.4], [6e3, 5e3], [0.2, 0.2], ratio=2.0, name="a"),
            dd.Branch(1, [0.6], [4e3], [0.3], ratio=-3.5, name="b")]
shaft = dd.Shaft([1.0, 0.3, 0.9], [1e4, 1.2e4, 9e3], [0.5, 0.8, 0.3], left="clamped",
                 branches=branches)
omega_n = dd.shaft_frequencies(shaft)
print("natural frequencies [rad/s]:", np.round(omega_n, 2))

omega = np.linspace(0.0, 1.2 * omega_n.max(), 3000)
H = dd.shaft_frequency_response(shaft, omega, ["main.0"], ["main.2", "a.1", "b.0"])

fig, ax = plt.subplots(figsize=(7, 4))
for j, name in enumerate(["main.2", "a.1", "b.0"]):
    ax.semilogy(omega, np.abs(H[:, j, 0]), label=f"phi {name} / T main.0")
for w in omega_n:
    ax.axvline(w, color="0.8", lw=0.8)
ax.set_xlabel("omega [rad/s]")
ax.set_ylabel("|receptance| [rad / N m]")
ax.legend()
fig.tight_layout()
plt.show()
