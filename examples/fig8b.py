# Paper Fig. 8b from Python: the FRF of the bistable oscillator coupled with a resonator over alpha x Omega
# (201 x 201, the paper's settings; examples/paper_fig8_frf.toml). Cells in the "# %%" form run in
# VS Code/Jupyter/Spyder; as a script: python3 examples/fig8b.py (writes fig8b.png; ~10 s on 2 cores).
# %%
import os
import matplotlib.pyplot as plt
import bistable

spec = os.path.join(os.path.dirname(os.path.abspath(__file__)), "paper_fig8_frf.toml")
ds = bistable.run(spec, progress=True)  # cached in ./bistable-data: a second run is instant
# %%
fig, ax = plt.subplots(figsize=(6.4, 4.8), constrained_layout=True)
ds.frf_db.plot(ax=ax, x="omega", y="alpha", cmap="jet", cbar_kwargs={"label": "FRF [dB]"})
ds.frf_db.plot.contour(ax=ax, x="omega", y="alpha", levels=[0.0], colors="k", linewidths=0.8)
ax.set(xlabel=r"$\Omega = \omega_0/\omega_n$", ylabel=r"$\alpha = A_0/\delta_s$",
       title=r"Fig. 8b: coupled, $\lambda$ = %.2g, $\phi$ = %.2g (black: 0 dB)" % (ds["lambda"], ds.phi))
fig.savefig("fig8b.png", dpi=150)
