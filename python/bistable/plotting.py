"""bistable.plot: a map variable as a labelled matplotlib figure, code variables by their category names.

xarray labels a plot from the variable's long_name and units (or, without units, its `unit`: the map files'
scale of a dimensionless quantity, e.g. "1/tau"), so ds.frf_db.plot() needs no help. It knows nothing of
CF's flag_values/flag_meanings, and draws a code variable (motion, termination, attractor, refine_fill)
as a continuous field. plot() draws those with one colour per code and the colour bar (or, for a line, the
y axis) labelled with the codes' names; every other variable is passed to xarray's own plot().
"""

# One colour per code, in flag_values order: grey for the first (motion's "undefined"), then matplotlib's
# tab10 without its grey.
_COLOURS = ["#7f7f7f", "#1f77b4", "#ff7f0e", "#d62728", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#bcbd22",
            "#17becf"]


def categories(da):
    """[(code, name), ...] of a CF flag variable, in code order; None for a variable without flags."""
    import numpy as np

    values, meanings = da.attrs.get("flag_values"), da.attrs.get("flag_meanings")
    if values is None or meanings is None:
        return None
    codes = [int(v) for v in np.atleast_1d(values)]
    names = str(meanings).split()
    if len(codes) != len(names) or not codes:
        raise ValueError("%s: flag_values (%d) and flag_meanings (%d) differ in count" %
                         (da.name, len(codes), len(names)))
    return sorted(zip(codes, names))


def plot(da, **kw):
    """Plots a DataArray of a map: da.plot(**kw), but a code variable (CF flag_values/flag_meanings, e.g.
    ds.motion) with one colour per category and the categories' names on the colour bar (2-D) or the y
    axis (1-D). Returns what xarray's plot returns (the QuadMesh of a 2-D plot, a FacetGrid with col= or row=,
    the lines of a 1-D one)."""
    cats = categories(da)
    if cats is None:
        return da.plot(**kw)
    import matplotlib.colors as mcolors

    codes = [c for c, _ in cats]
    names = [n for _, n in cats]
    if da.ndim == 1:
        kw.setdefault("marker", "o")
        kw.setdefault("linestyle", "none")
        lines = da.plot(**kw)
        ax = lines[0].axes
        ax.set_yticks(codes)
        ax.set_yticklabels(names)
        ax.set_ylabel(da.attrs.get("long_name", da.name))
        return lines
    # Boundaries halfway between consecutive codes, so each code gets one colour of its own.
    bounds = [codes[0] - 0.5] + [(a + b) / 2 for a, b in zip(codes, codes[1:])] + [codes[-1] + 0.5]
    colours = (_COLOURS * (len(codes) // len(_COLOURS) + 1))[:len(codes)]
    cmap = mcolors.ListedColormap(colours)
    kw.setdefault("cmap", cmap)
    kw.setdefault("norm", mcolors.BoundaryNorm(bounds, cmap.N))
    cbar_kwargs = dict(kw.pop("cbar_kwargs", None) or {})
    cbar_kwargs.setdefault("ticks", codes)
    cbar_kwargs.setdefault("label", da.attrs.get("long_name", da.name))
    mesh = da.plot(cbar_kwargs=cbar_kwargs, **kw)
    colorbar = getattr(mesh, "colorbar", None) or getattr(mesh, "cbar", None)  # a plot's, or a FacetGrid's (col=)
    if colorbar is not None:
        colorbar.set_ticks(codes)
        colorbar.set_ticklabels(names)
    return mesh
