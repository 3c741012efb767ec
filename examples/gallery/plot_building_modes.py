"""
Modes of a shear building
=========================

The natural modes of a 5-storey shear building (floor masses 200 t, storey stiffnesses
300 MN/m, the top one 200 MN/m) by `mck_modes`: frequencies, mass-normalized shapes and the
effective modal mass of each mode for a horizontal ground motion.
"""
import matplotlib.pyplot as plt
import numpy as np

import dtdyn as dd

M, C, K = dd.chain_matrices([2e5] * 5, [3e8] * 4 + [2e8], [0.0] * 5, sparse=False)
m = dd.mck_modes(M, None, K)
for i in range(5):
    print(f"mode {i + 1}: {m.frequency_hz[i]:6.2f} Hz, omega {m.omega[i]:6.2f} rad/s, "
          f"effective mass {100 * m.effective_mass_ratio[i]:5.1f} %")

fig, axes = plt.subplots(1, 5, sharey=True, figsize=(9, 4))
floors = np.arange(6)
for i, ax in enumerate(axes):
    shape = np.r_[0.0, m.shapes[:, i]]
    shape /= np.abs(shape).max()
    ax.plot(shape, floors, "o-")
    ax.axvline(0.0, color="0.7", lw=0.8)
    ax.set_title(f"{m.frequency_hz[i]:.2f} Hz")
    ax.set_xlim(-1.2, 1.2)
axes[0].set_ylabel("floor")
fig.suptitle("mass-normalized mode shapes (scaled to 1)")
fig.tight_layout()
plt.show()
