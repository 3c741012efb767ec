"""
A nonlinear response: P4's cubic springs
========================================

Problem P4 (a 4-DOF chain with two cubic springs, a random force on the last mass) by
`nonlinear_mck_response` with the explicit modal method at one and two sub-steps, and the
linear chain without its cubic springs for comparison. The difference between the two
nonlinear runs estimates the error of the first.
"""
import matplotlib.pyplot as plt
import numpy as np

import dtdyn as dd

p = dd.problem("P4", n_samples=4000)
args = (p["M"], p["C"], p["K"], p["force"], p["dt"])
one = dd.nonlinear_mck_response(*args, force_dofs=p["force_dofs"], elements=p["elements"],
                                scheme="modal_explicit", substeps=1, estimate=False)
two = dd.nonlinear_mck_response(*args, force_dofs=p["force_dofs"], elements=p["elements"],
                                scheme="modal_explicit", substeps=2, estimate=False)
linear = dd.exact_response(*args, force_dofs=p["force_dofs"])
dof = 3
scale = np.abs(two.x[:, dof]).max()
print(f"1 vs 2 sub-steps: {np.abs(one.x[:, dof] - two.x[:, dof]).max() / scale:.1e} "
      f"(relative), run time {one.info['run_time'] * 1e3:.1f} ms")

fig, ax = plt.subplots(figsize=(7, 4))
ax.plot(linear.t, linear.x[:, dof], color="0.6", label="linear (no cubic springs)")
ax.plot(two.t, two.x[:, dof], label="nonlinear, modal_explicit")
ax.set_xlabel("t [s]")
ax.set_ylabel(f"x of DOF {dof} [m]")
ax.legend()
fig.tight_layout()
plt.show()
