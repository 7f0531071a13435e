"""Figures (PNG, off-screen pyvista). Without pyvista they are skipped with one line."""
import os
import sys

import numpy as np
from mpi4py import MPI
from scipy.spatial import cKDTree

from dolfrag.post.fragment_sizes import grady_count, mott_count

# the concrete's opacity in a figure that draws the rebars inside it
BAR_OPACITY = 0.45


def milliseconds(t):
    """A time t (s) as every figure writes it: in ms, to three significant digits
    (6.00 ms, 0.200 ms, 0.0800 ms, 125 ms)."""
    ms = 1e3 * t
    decimals = 2 if ms == 0 else max(0, 2 - int(np.floor(np.log10(abs(ms)))))
    return f"{ms:.{decimals}f} ms"


def figure_title(case_name, t):
    """The head of a figure of a run's state: the case and its time t (s),
    e.g. "wall-bending-clamped, t = 6.00 ms"."""
    return f"{case_name}, t = {milliseconds(t)}"


# the time axis of every figure: ms, as milliseconds() writes a time
TIME_SCALE, TIME_UNIT = 1e3, "ms"


def _gather_broken_mesh(space, displacement, values, cell_offset=None, cells=None):
    """Owned cells' corner coordinates (+ displacement, flat per dof component, + the
    cell's offset (n_owned_cells, gdim) if given) and per-dof values, gathered on rank 0
    (None elsewhere). cells (n_owned_cells,) bool: only those (all if None)."""
    keep = np.ones(space.n_owned_cells, bool) if cells is None else np.asarray(cells, bool)
    corners = space.cell_dofs[:space.n_owned_cells][keep].ravel()
    points = space.x[corners] + displacement.reshape(-1, space.gdim)[corners]
    if cell_offset is not None:
        points += np.repeat(cell_offset[keep], space.gdim + 1, axis=0)
    gathered = space.mesh.comm.gather((points, values[corners]), root=0)
    if gathered is None:
        return None
    return np.concatenate([g[0] for g in gathered]), np.concatenate([g[1] for g in gathered])


def broken_mesh_png(space, u, values, path, label, title, scale=None, cell_offset=None, note="", cells=None,
                    view=None, rebars=None, clim=None):
    """The broken (DG) mesh deformed by ``scale * u`` and coloured by ``values`` (n_dofs,),
    one per local dof (e.g. the speed, or the damage), with the axes in m at round ticks, a
    scale bar of a round length and a colour bar titled ``label`` (the quantity and its
    unit) over ``clim`` (lo, hi): DAMAGE_RANGE, SIGNED (symmetric about 0, for a component)
    or None (0 to the largest value). When ``scale`` is None the largest displacement is
    drawn as 2 % of the body size. cell_offset (n_owned_cells, gdim) m: moves each owned
    cell as a whole (e.g. ``exploded``). cells (n_owned_cells,) bool: draw only those (e.g.
    half a slab, so that the cut shows the cracks inside). view (3,): in 3D, the direction
    from the body towards the camera, z up (default (1, 1, 1), isometric). rebars
    (rebar/cables.Rebars): the bars drawn as black lines, deformed alike (those in ``cells``), over
    concrete made translucent so that the bars inside it show. ``title`` (``figure_title``:
    the case and the time) heads the figure, ``note`` follows the displacement scale below it.
    Collective; rank 0 draws and returns the figure's ``contents`` (None elsewhere)."""
    d = space.gdim
    comm = space.mesh.comm
    umax = comm.allreduce(np.abs(u.x.array[:space.n_owned_dofs * d]).max(initial=0.0), op=MPI.MAX)
    size = comm.allreduce(np.ptp(space.x, axis=0).max() if len(space.x) else 0.0, op=MPI.MAX)
    if scale is None:
        scale = 0.02 * size / umax if umax > 0 else 1.0
    data = _gather_broken_mesh(space, scale * u.x.array, values, cell_offset, cells)
    bars = None if rebars is None else _gather_bars(rebars, u.x.array, scale, cells, comm)
    if data is None:
        return None
    try:
        import pyvista as pv
    except ImportError:
        print(f"pyvista is not installed: {path} not drawn (pip install pyvista)", file=sys.stderr)
        return None
    # Off-screen through EGL directly: VTK would try an X server first and warn.
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    points, values = data
    nv = d + 1
    points = np.column_stack([points, np.zeros((len(points), 3 - d))])
    n_cells = len(points) // nv
    conn = np.column_stack([np.full(n_cells, nv), np.arange(n_cells * nv).reshape(-1, nv)]).ravel()
    cell_type = pv.CellType.TRIANGLE if nv == 3 else pv.CellType.TETRA
    grid = pv.UnstructuredGrid(conn, np.full(n_cells, cell_type, np.uint8), points)
    grid.point_data[label] = values
    lo, hi = colour_range(values, clim)
    lows, highs = np.array(grid.bounds[::2]), np.array(grid.bounds[1::2])
    steps = tick_steps(highs[:d] - lows[:d]) + [1.0]  # 2D: z is 0
    axes = [round_axis(a, b, step) for a, b, step in zip(lows, highs, steps)]
    box, ticks = np.array([a[:2] for a in axes]), [a[2] for a in axes]
    plotter = pv.Plotter(off_screen=True, window_size=window_size(box[:, 1] - box[:, 0], d))
    plotter.add_mesh(grid, scalars=label, cmap="RdBu_r" if clim is SIGNED else "viridis", clim=(lo, hi),
                     opacity=1.0 if bars is None else BAR_OPACITY,
                     scalar_bar_args={"title": label, "vertical": True, "position_x": 0.86, "position_y": 0.2,
                                      "width": 0.04, "height": 0.6, "fmt": "%.3g", "n_labels": 5,
                                      "title_font_size": 14, "label_font_size": 12})
    if bars is not None and len(bars):
        ends = np.concatenate([bars, np.zeros((*bars.shape[:2], 3 - d))], axis=2).reshape(-1, 3)
        lines = np.column_stack([np.full(len(bars), 2), np.arange(2 * len(bars)).reshape(-1, 2)]).ravel()
        plotter.add_mesh(pv.PolyData(ends, lines=lines), color="black", line_width=2)
    caption = plotter.add_text(f"{title}\ndisplacement x {scale:.3g}" + (f"; {note}" if note else ""),
                               position="upper_left", font_size=10)
    view = np.array([0.0, 0.0, 1.0] if d == 2 else (1.0, 1.0, 1.0) if view is None else view)
    _ruler(plotter, pv, box, ticks, steps, view, d)
    if d == 2:
        plotter.view_xy()
    else:
        plotter.view_vector(view, viewup=(0.0, 0.0, 1.0))
    _frame(plotter, box, d)
    if d == 3:
        _unlabel_shared_corners(plotter, box, ticks)
    plotter.screenshot(str(path))
    drawn = contents(plotter, caption, label)
    plotter.close()
    return drawn


def _gather_bars(rebars, u, scale, cells, comm):
    """The rebar segments each rank counts (those in ``cells``, if given) at displacement u
    magnified ``scale`` times, (n, 2, d) m, gathered on rank 0 (None elsewhere)."""
    keep = rebars.counted.copy()
    if cells is not None:
        keep[keep] = np.asarray(cells, bool)[rebars.cell_a[keep]]
    gathered = comm.gather(rebars.segments(u, scale)[keep], root=0)
    return None if gathered is None else np.concatenate(gathered)


def round_length(most):
    """The largest 1, 2 or 5 x 10^k not above ``most`` (> 0)."""
    power = 10.0 ** np.floor(np.log10(most))
    return max(f * power for f in (1, 2, 5) if f * power <= most * (1 + 1e-12))


def round_axis(lo, hi, step):
    """An axis' limits (m) and its number of ticks: lo, hi widened outwards to multiples of
    ``step`` (a body out by 1 % of a step, e.g. by its displacement, does not add one: the
    box's line hides so little). VTK's cube axes then tick round values."""
    first, last = np.floor(lo / step + 0.01), np.ceil(hi / step - 0.01)
    return step * first, step * last, int(last - first) + 1


def tick_steps(spans):
    """Each axis' tick step (m): a round length (1, 2 or 5 x 10^k) at most a third of its
    span and no less than a tenth of the largest span, so that a thin slab's axis does not
    crowd its labels."""
    largest = max(spans)
    return [round_length(max(span / 3, largest / 10)) for span in spans]


DAMAGE_RANGE = (0.0, 1.0)  # damage 1 - beta: intact to broken, whatever the run reached
SIGNED = "signed"          # broken_mesh_png's clim for a component: symmetric about 0


def colour_range(values, clim):
    """The colour bar's (lo, hi): ``clim`` when given as a pair; for SIGNED, -m to m, else 0
    to m, with m the largest |value| (1 for a field that is zero everywhere, where any range
    would read 0 ... 0)."""
    if clim is not None and clim is not SIGNED:
        return tuple(clim)
    largest = float(np.abs(values).max(initial=0.0)) or 1.0
    return (-largest, largest) if clim is SIGNED else (0.0, largest)


def window_size(extent, d):
    """(width, height) px of a field figure: in 2D as tall as the box of ``extent`` (m) needs
    beside the colour bar, between 450 and 900 px, so that a slender wall fills its width;
    in 3D 1200 x 800."""
    if d == 3:
        return 1200, 800
    return 1200, int(np.clip(900 * extent[1] / extent[0] + 260, 450, 900))


def _ruler(plotter, pv, box, ticks, steps, view, d):
    """Axes (m) around ``box`` (3, 2) with ``ticks`` (3,) labels each, ``steps`` (m) apart
    (round_axis; a sum's rounding error at 0 written 0), and a black scale bar a
    quarter of the box's largest extent long (rounded) along x: in 2D above the box's right
    end, in 3D behind the body as the camera (``view``: from the body towards it) sees it."""
    lo, hi = box[:, 0], box[:, 1]
    plotter.show_bounds(bounds=box.ravel(), xtitle="x (m)", ytitle="y (m)", ztitle="z (m)", show_zaxis=d == 3,
                        location="outer", font_size=12 if d == 3 else 10, use_2d=d == 2, fmt="%.4g",
                        n_xlabels=ticks[0], n_ylabels=ticks[1], n_zlabels=ticks[2])
    cube = plotter.renderer.cube_axes_actor
    for axis, step in enumerate(steps[:d]):
        labels = cube.GetAxisLabels(axis)
        values = [float(labels.GetValue(k)) for k in range(labels.GetNumberOfValues())]
        clean = pv.convert_string_array(np.array([f"{v if abs(v) > 1e-9 * step else 0.0:.4g}" for v in values]))
        cube.SetAxisLabels(axis, clean)
    size = (hi - lo).max()
    length = round_length(0.25 * size)
    if d == 2:
        start = np.array([hi[0] - length, hi[1] + 0.06 * size, 0.0])
    else:
        near, far = np.where(view > 0, hi, lo), np.where(view > 0, lo, hi)  # the corners nearest, farthest
        # behind the body, at the camera's height: above its silhouette, clear of the axes' labels
        start = np.array([near[0] - length if view[0] > 0 else near[0],
                          far[1] - np.sign(view[1] or -1) * 0.12 * size, near[2]])
    plotter.add_mesh(pv.Line(start, start + [length, 0.0, 0.0]), color="black", line_width=5)
    above = [0.0, 0.03 * size, 0.0] if d == 2 else [0.0, 0.0, 0.06 * size]  # the label clear of the bar
    plotter.add_point_labels([start + [length / 2, 0.0, 0.0] + above],
                             [f"{length * 1e3:g} mm" if length < 1 else f"{length:g} m"],
                             font_size=14, point_size=1, shape=None, always_visible=True)


# each corner's neighbours along x, y, z (corner i: bit 0 x, bit 1 y, bit 2 z at the box's high end)
_NEIGHBOURS = [[i ^ 1, i ^ 2, i ^ 4] for i in range(8)]


def outer_edges(corners):
    """The box edges VTK's cube axes draw in their "outer" fly mode (FindBoundaryEdge), from
    the box's 8 corners in display coordinates ``corners`` (8, 3): px and depth, corner i at
    the high end of x if bit 0 of i, of y if bit 1, of z if bit 2. Returns {axis: (i, j)}:
    for each axis the two corners of its edge."""
    pts = np.asarray(corners, float)
    start = int(np.argmin(pts[:, 0] ** 2 + pts[:, 1] ** 2))  # nearest the viewport's lower left
    first, slope, least = 0, 0.0, np.inf
    for i, n in enumerate(_NEIGHBOURS[start]):  # the flattest edge to the right
        num, den = pts[n, 1] - pts[start, 1], pts[n, 0] - pts[start, 0]
        slope = num / den if den != 0.0 else slope
        if slope < least and den > 0:
            first, least = i, slope
    ends = [_NEIGHBOURS[start][(first + k) % 3] for k in range(3)]
    e1, e2, e3 = (pts[n] - pts[start] for n in ends)
    e1, e2, e3 = (e / (np.linalg.norm(e) or 1.0) for e in (e1, e2, e3))
    second, other = ((first + 1) % 3, ends[1]) if e1 @ e2 < e1 @ e3 else ((first + 2) % 3, ends[2])
    third = 3 - first - second
    a, b = _NEIGHBOURS[ends[0]][third], _NEIGHBOURS[other][third]
    base = ends[0] if pts[a, 2] < pts[b, 2] else other
    return {first: (start, ends[0]), second: (start, other), third: (base, _NEIGHBOURS[base][third])}


def _unlabel_shared_corners(plotter, box, ticks):
    """In 3D, two axes drawn from one corner of the box would write their end labels over
    each other there ("1" beside "1"): at each such corner the label of the axis with more
    ticks (y before x before z on a tie) is left blank, its tick still drawn. Call with the
    camera set, before the screenshot."""
    renderer = plotter.renderer
    plotter.render()  # the viewport's aspect, as the cube axes see it
    corners = []
    for i in range(8):
        renderer.SetWorldPoint(*(box[k, (i >> k) & 1] for k in range(3)), 1.0)
        renderer.WorldToDisplay()
        corners.append(renderer.GetDisplayPoint())
    edges = outer_edges(corners)
    cube = renderer.cube_axes_actor
    labels = [cube.GetAxisLabels(k) for k in range(3)]
    for corner in set(edges[0]) | set(edges[1]) | set(edges[2]):
        meeting = [k for k in range(3) if corner in edges[k]]
        if len(meeting) < 2:
            continue
        axis = max(meeting, key=lambda k: (ticks[k], (1, 0, -1)[k]))
        end = (corner >> axis) & 1  # the axis' last tick at the high end, its first at the low
        labels[axis].SetValue(labels[axis].GetNumberOfValues() - 1 if end else 0, "")
        labels[axis].Modified()
    for k in range(3):
        cube.SetAxisLabels(k, labels[k])


def _frame(plotter, box, d):
    """The camera: in 2D a parallel projection (a drawing) in which the axes' ``box`` (3, 2)
    fills the width left of the colour bar, or the height below the caption; in 3D fitted
    to everything drawn. Either way the picture is moved left, off the colour bar."""
    if d == 2:
        width, height = plotter.window_size
        extent = box[:2, 1] - box[:2, 0]
        plotter.enable_parallel_projection()
        plotter.camera.focal_point = (*box[:2].mean(axis=1), 0.0)
        plotter.camera.position = (*box[:2].mean(axis=1), 10.0 * extent.max())
        # half the view's height (m): the box in 65 % of the width, or 55 % of the height
        plotter.camera.parallel_scale = max(extent[0] / 0.65 * height / width, extent[1] / 0.55) / 2
    else:
        plotter.reset_camera()
    plotter.camera.SetWindowCenter(0.12 if d == 2 else 0.08, 0.0)


def contents(plotter, caption, label):
    """What a field figure shows, read back from its actors: the caption, the colour bar
    (title, lo, hi) and each axis' tick labels by its title."""
    bar = plotter.scalar_bars[label]
    axes = plotter.renderer.cube_axes_actor
    ticks = {}
    for i, (title, shown) in enumerate(((axes.GetXTitle(), axes.GetXAxisVisibility()),
                                        (axes.GetYTitle(), axes.GetYAxisVisibility()),
                                        (axes.GetZTitle(), axes.GetZAxisVisibility()))):
        labels = axes.GetAxisLabels(i)
        if shown:
            ticks[title] = [labels.GetValue(k) for k in range(labels.GetNumberOfValues())]
    return {"caption": caption.GetText(caption.UpperLeft),
            "colour_bar": (bar.GetTitle(), *bar.GetLookupTable().GetRange()), "axes": ticks}


def exploded(frags, fragment_of_cell, spread):
    """Offset (n_owned_cells, gdim) m of each owned cell for an exploded view: its
    fragment's centroid offset from the body's mass centre, times ``spread`` (-). Every cut
    facet then opens by ``spread`` times the distance between the two fragments' centroids.
    frags: post.fragments.Fragments; fragment_of_cell (n_owned_cells,) int, from
    ``fragments(..., of_cells=True)``."""
    centre = frags.mass @ frags.centroid / frags.mass.sum()
    return spread * (frags.centroid - centre)[fragment_of_cell]


def signal_png(signal, t_end, path, comm, title=""):
    """The load's pressure p(t) (``signal``: Pa, a vectorised function of t in s) over
    [0, t_end] s, drawn with matplotlib in MPa and ms.
    Collective; rank 0 draws."""
    plt = _pyplot(comm, path)
    if plt is None:
        return
    t = np.linspace(0.0, t_end, 2001)
    fig, ax = plt.subplots(figsize=(7, 3.5), layout="constrained")
    ax.plot(TIME_SCALE * t, 1e-6 * signal(t))
    ax.set_xlabel(f"time t ({TIME_UNIT})")
    ax.set_ylabel("pressure p (MPa), > 0 pushes in")
    ax.set_xlim(0.0, TIME_SCALE * t_end)
    ax.set_ylim(bottom=min(0.0, ax.get_ylim()[0]))
    ax.set_title(title)
    ax.grid(alpha=0.3)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def charge_png(charge, t_end, path, comm, title=""):
    """A charge's load (loads.charge_load.ChargeLoad): p(t) over [0, t_end] s at the nearest
    and farthest loaded facets and the mean over the loaded boundary, then maps of each
    facet's peak pressure and positive impulse, on the two axes along which the loaded
    facets spread most. Collective; rank 0 draws."""
    plt = _pyplot(comm, path)
    if plt is None:
        return
    f = charge.facets
    near, far = charge.extremes()
    t = np.linspace(0.0, t_end, 2001)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2), layout="constrained")
    for index, name in ((near, "nearest"), (far, "farthest")):
        axes[0].plot(TIME_SCALE * t, 1e-6 * charge.point_pressure(index)(t),
                     label=f"{name}: R = {f['R'][index]:.3g} m, Z = {f['Z'][index]:.3g} m/kg^(1/3)")
    axes[0].plot(TIME_SCALE * t, 1e-6 * charge.mean_pressure(t), "k--", label="mean over the face")
    axes[0].set_xlabel(f"time t ({TIME_UNIT})")
    axes[0].set_ylabel("pressure p (MPa), > 0 pushes in")
    axes[0].set_xlim(0.0, TIME_SCALE * t_end)
    axes[0].legend(fontsize="small")
    axes[0].grid(alpha=0.3)
    a, b = np.argsort(np.ptp(f["x"], axis=0))[::-1][:2]
    for ax, values, label in ((axes[1], 1e-6 * f["P"], "peak reflected pressure P_r (MPa)"),
                              (axes[2], 1e-3 * f["i"], "reflected impulse i_r (kPa s)")):
        dots = ax.scatter(f["x"][:, a], f["x"][:, b], c=values, s=6, cmap="viridis")
        fig.colorbar(dots, ax=ax, label=label)
        ax.set_xlabel(f"{'xyz'[a]} (m)")
        ax.set_ylabel(f"{'xyz'[b]} (m)")
        ax.set_aspect("equal")
    fig.suptitle(title)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _pyplot(comm, path):
    """matplotlib.pyplot (Agg) on rank 0; None elsewhere or without matplotlib."""
    if comm.rank != 0:
        return None
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print(f"matplotlib is not installed: {path} not drawn (pip install matplotlib)", file=sys.stderr)
        return None
    return plt


OFF_SCALE = 5.0  # deflection_png: an estimate this far above the run is cut at the run's scale


def deflection_png(t, w, sdof, path, comm, title="", cracked_at=None, estimate="elastic SDOF (Biggs)"):
    """Midspan deflection w(t) (m) of a wall run against the closed-form estimate ``sdof`` =
    (t, y) (s, m) or None, named ``estimate``, with the first through-crack's time (s)
    marked. An estimate more than OFF_SCALE times the run's largest deflection (a
    quasi-static one under a short pulse) is cut at the run's scale and says so.
    Collective; rank 0 draws."""
    plt = _pyplot(comm, path)
    if plt is None:
        return
    fig, ax = plt.subplots(figsize=(7, 3.5), layout="constrained")
    ax.plot(TIME_SCALE * np.asarray(t), 1e3 * np.asarray(w), label="dolfrag (mean across the section)")
    if sdof is not None:
        largest = np.abs(w).max(initial=0.0)
        off_scale = largest > 0 and np.abs(sdof[1]).max() > OFF_SCALE * largest
        ax.plot(TIME_SCALE * sdof[0], 1e3 * sdof[1], "--", label=estimate + (" (off scale)" if off_scale else ""))
        if off_scale:
            ax.set_ylim(-1.1e3 * largest, 1.1e3 * largest)
    if cracked_at is not None:
        ax.axvline(TIME_SCALE * cracked_at, color="k", lw=0.8, ls=":", label="first through-crack")
    ax.set_xlabel(f"time t ({TIME_UNIT})")
    ax.set_ylabel("deflection (mm)")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def wave_png(t, y, v, thickness, path, comm, title="", depths=100):
    """The wave through a wall's thickness (Fig. 7 of the reference paper): velocity v (m/s) across the
    thickness over time at midspan, as a time-depth map. t (k,) s; y, v: per time, the
    depths (m) and velocities of the midspan dofs, interpolated linearly in depth.
    Collective; rank 0 draws."""
    plt = _pyplot(comm, path)
    if plt is None:
        return
    grid = np.linspace(0.0, thickness, depths)
    order = [np.argsort(yk, kind="stable") for yk in y]
    image = np.array([np.interp(grid, yk[o], vk[o]) for yk, vk, o in zip(y, v, order)])
    fig, ax = plt.subplots(figsize=(7, 3.5), layout="constrained")
    limit = np.abs(image).max(initial=0.0) or 1.0
    mesh = ax.pcolormesh(TIME_SCALE * np.asarray(t), 1e3 * grid, image.T, cmap="RdBu_r",
                         vmin=-limit, vmax=limit, shading="nearest")
    fig.colorbar(mesh, ax=ax, label="velocity across the wall (m/s)")
    ax.set_xlabel(f"time t ({TIME_UNIT})")
    ax.set_ylabel("depth across the thickness (mm)")
    ax.set_title(title)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def fragment_masses_png(masses, fits, path, comm, title=""):
    """The cumulative number N(>m) of fragments heavier than m against m, log-log, with the
    fitted Grady and Mott distributions (``fits``: post.fragment_sizes.block of ``masses``,
    in its unit) and their mass scales mu. Collective; rank 0 draws."""
    plt = _pyplot(comm, path)
    if plt is None:
        return
    unit = fits["unit"]
    m = np.sort(np.asarray(masses))[::-1]
    fig, ax = plt.subplots(figsize=(7, 4.5), layout="constrained")
    ax.loglog(m, np.arange(1, len(m) + 1), "o", ms=4, label=f"dolfrag ({len(m)} fragments)")
    if fits["grady"] is not None:
        grid = np.geomspace(m[-1], m[0], 200)
        for name, count, style in (("grady", grady_count, "--"), ("mott", mott_count, ":")):
            mu, error = fits[name]["mu"], fits[name]["standard_error"]
            formula = "exp(-m/mu)" if name == "grady" else "exp(-(m/mu)^1/2)"
            ax.loglog(grid, count(grid, len(m), mu), style,
                      label=f"{name.capitalize()} N0 {formula}: mu = {mu:.3g} ± {error:.2g} {unit}")
        ax.set_ylim(bottom=0.5)
    else:
        ax.text(0.5, 0.5, "fewer than 2 fragments: no fit", transform=ax.transAxes, ha="center")
    ax.set_xlabel(f"fragment mass m ({unit})")
    ax.set_ylabel("fragments heavier than m, N(>m)")
    ax.set_title(title)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=120)
    plt.close(fig)


DENSITY_LEVELS = (1, 2, 5, 10, 20, 50)  # debris_map_png: hazardous fragments per hazard_area


def debris_map_png(debris, footprint, block, path, comm, title=""):
    """Plan view (x, y in m) of where the debris lands: the structure's footprint (k, 2) m
    outlined, each landing point sized by its mass and coloured by its impact energy (J),
    the hazardous ones (``block["hazard_energy_J"]``) ringed, contours of the areal density
    of hazardous fragments (their count within a circle of area ``block["hazard_area_m2"]``
    around each point: 1 is the limit) and the hazard distance around the centre.
    debris: post.debris.Throw; block: its post.debris.block. Collective; rank 0 draws."""
    plt = _pyplot(comm, path)
    if plt is None:
        return
    from matplotlib.colors import LogNorm  # matplotlib is optional: imported where it is there

    centre, hazard_area = np.asarray(block["centre_m"]), block["hazard_area_m2"]
    hazardous = debris.impact_energy >= block["hazard_energy_J"]
    reach = max(np.abs(footprint - centre).max(), block["largest_range_m"], block["hazard_distance_m"])
    extent = 1.15 * reach
    fig, ax = plt.subplots(figsize=(7, 6), layout="constrained")
    outline = np.vstack([footprint, footprint[:1]])
    ax.fill(outline[:, 0], outline[:, 1], color="0.85", ec="k", lw=1.2, label="structure (footprint)")
    if hazardous.any():
        x, y = np.meshgrid(*(np.linspace(c - extent, c + extent, 201) for c in centre))
        radius = np.sqrt(hazard_area / np.pi)
        count = cKDTree(debris.landing[hazardous, :2]).query_ball_point(np.column_stack([x.ravel(), y.ravel()]),
                                                                        radius, return_length=True)
        # the counts are integers: a line half-way between n - 1 and n bounds the area of >= n
        levels = np.array(DENSITY_LEVELS) - 0.5
        ax.contourf(x, y, count.reshape(x.shape), levels=[levels[0], np.inf], colors="red", alpha=0.08)
        lines = ax.contour(x, y, count.reshape(x.shape), levels=levels, colors="red",
                           linewidths=[1.5] + [0.6] * (len(levels) - 1))
        ax.clabel(lines, fmt={level: f">= {level + 0.5:g}" for level in levels}, fontsize=7)
    energy = debris.impact_energy
    if len(energy):
        low, high = energy[energy > 0].min(initial=np.inf), energy.max()
        wide = np.isfinite(low) and high > 10 * low  # energies over decades: a log scale, zeros at its floor
        points = ax.scatter(debris.landing[:, 0], debris.landing[:, 1], s=10 + 200 * debris.mass / debris.mass.max(),
                            c=np.maximum(energy, low) if wide else energy, norm=LogNorm(low, high) if wide else None,
                            cmap="viridis", edgecolors=np.where(hazardous, "red", "none"), linewidths=1.0, zorder=3)
        fig.colorbar(points, ax=ax, label="impact energy 1/2 m v^2 (J)")
    if block["hazard_distance_m"] > 0:
        angle = np.linspace(0.0, 2 * np.pi, 361)
        ax.plot(centre[0] + block["hazard_distance_m"] * np.cos(angle),
                centre[1] + block["hazard_distance_m"] * np.sin(angle), "r--", lw=1.0, label="hazard distance")
    ax.plot(*centre, "k+", ms=10, label="centre")
    ax.set_xlim(centre[0] - extent, centre[0] + extent)
    ax.set_ylim(centre[1] - extent, centre[1] + extent)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{title}\n{block['thrown']} thrown, {block['hazardous']} hazardous (>= "
                 f"{block['hazard_energy_J']:g} J, ringed red); hazard distance {block['hazard_distance_m']:.3g} m\n"
                 f"contours: hazardous fragments per {hazard_area:g} m^2 (1: the limit); marker area ~ mass",
                 fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    fig.savefig(path, dpi=120)
    plt.close(fig)
