"""
A chain's response against the exact solution
==============================================

Problem P3 (Kumar and Sankar's undamped 15-mass chain, a unit step force on the last mass) run
by the DT-TMM sweep with three schemes at dt = 1 ms, each compared with the exact response of
the force linear between samples (the matrix exponential, `exact_response`).
"""
import matplotlib.pyplot as plt
import numpy as np

import dtdyn as dd

p = dd.problem("P3")
dt, force = 1e-3, np.ones(801)
ref = dd.exact_response(p["M"], p["C"], p["K"], force, dt, force_dofs=[14], outputs=[14])

fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(7, 5.5))
top.plot(ref.t, ref.x[:, 0], "k", lw=2, label="exact")
for scheme in ("average_acceleration", "fox_goodwin", "hht"):
    r = dd.chain_response(p["mass"], p["stiffness"], p["damping"], force, dt,
                          force_dofs=[14], outputs=[14], scheme=scheme)
    error = np.abs(r.x[:, 0] - ref.x[:, 0]) / np.abs(ref.x).max()
    print(f"{scheme:22s} max relative error {error.max():.1e}")
    top.plot(r.t, r.x[:, 0], "--", label=scheme)
    bottom.semilogy(r.t[1:], error[1:], label=scheme)
top.set_ylabel("x of mass 15 [m]")
top.legend()
bottom.set_xlabel("t [s]")
bottom.set_ylabel("|x - x_exact| / max |x|")
fig.tight_layout()
plt.show()
