# The double-well Duffing oscillator's stroboscopic bifurcation diagram from Python: the Poincare section
# stored by examples/duffing_poincare.toml (64 points per gamma = alpha Omega^2, phase 0) against gamma —
# period 1, the doubling cascade, chaos, the period-5 window. Cells in the "# %%" form run in
# VS Code/Jupyter/Spyder; as a script: python3 examples/duffing_poincare.py (writes duffing_poincare.png).
# %%
import os
import matplotlib.pyplot as plt
import bistable

spec = os.path.join(os.path.dirname(os.path.abspath(__file__)), "duffing_poincare.toml")
ds = bistable.run(spec)  # cached in ./bistable-data: a second run is instant
# %%
gamma = ds.alpha * float(ds.omega) ** 2  # the forcing amplitude alpha Omega^2
y = ds.poincare_y.transpose("alpha", "poincare_point")
fig, ax = plt.subplots(figsize=(7.2, 4.5), constrained_layout=True)
ax.plot(gamma.values.repeat(y.sizes["poincare_point"]), y.values.ravel(), ".", ms=0.8, mew=0, color="#2166ac")
ax.set(xlabel=r"$\gamma = \alpha\Omega^2$", ylabel=r"$y_m$ on the section $\Omega\tau \equiv 0$ [$\delta_s$]",
       title=r"$y'' + 0.3y' - y + y^3 = \gamma \sin 1.2\tau$: Poincare section, last %d strobes" % y.sizes["poincare_point"])
fig.savefig("duffing_poincare.png", dpi=150)
