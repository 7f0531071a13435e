"""Figures (PNG, off-screen pyvista). Without pyvista they are skipped with one line."""
import os
import sys

import numpy as np
from mpi4py import MPI


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


def broken_mesh_png(space, u, values, path, label, scale=None, cell_offset=None, note="", cells=None, view=None):
    """The broken (DG) mesh deformed by ``scale * u`` and coloured by ``values`` (n_dofs,),
    one per local dof (e.g. the speed, or the damage). When ``scale`` is None the largest
    displacement is drawn as 2 % of the body size. cell_offset (n_owned_cells, gdim) m:
    moves each owned cell as a whole (e.g. ``exploded``). cells (n_owned_cells,) bool: draw
    only those (e.g. half a slab, so that the cut shows the cracks inside). view (3,): in 3D,
    the direction from the body towards the camera, z up (default (1, 1, 1), isometric).
    ``note`` is added to the caption. Collective; rank 0 draws."""
    d = space.gdim
    comm = space.mesh.comm
    umax = comm.allreduce(np.abs(u.x.array[:space.n_owned_dofs * d]).max(initial=0.0), op=MPI.MAX)
    size = comm.allreduce(np.ptp(space.x, axis=0).max() if len(space.x) else 0.0, op=MPI.MAX)
    if scale is None:
        scale = 0.02 * size / umax if umax > 0 else 1.0
    data = _gather_broken_mesh(space, scale * u.x.array, values, cell_offset, cells)
    if data is None:
        return
    try:
        import pyvista as pv
    except ImportError:
        print(f"pyvista is not installed: {path} not drawn (pip install pyvista)", file=sys.stderr)
        return
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
    plotter = pv.Plotter(off_screen=True, window_size=(1200, 600))
    plotter.add_mesh(grid, scalars=label, cmap="viridis",
                     scalar_bar_args={"title": label, "vertical": False})
    plotter.add_text(f"displacement x {scale:.3g}" + (f"; {note}" if note else ""), font_size=10)
    if d == 2:
        plotter.view_xy()
    else:
        plotter.view_vector((1.0, 1.0, 1.0) if view is None else view, viewup=(0.0, 0.0, 1.0))
    plotter.screenshot(str(path))
    plotter.close()


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
    [0, t_end] s, drawn with matplotlib in MPa and µs (ms from t_end = 1 ms, s from 1 s).
    Collective; rank 0 draws."""
    plt = _pyplot(comm, path)
    if plt is None:
        return
    t = np.linspace(0.0, t_end, 2001)
    scale, unit = _time_unit(t_end)
    fig, ax = plt.subplots(figsize=(7, 3.5), layout="constrained")
    ax.plot(scale * t, 1e-6 * signal(t))
    ax.set_xlabel(f"time t ({unit})")
    ax.set_ylabel("pressure p (MPa), > 0 pushes in")
    ax.set_xlim(0.0, scale * t_end)
    ax.set_ylim(bottom=min(0.0, ax.get_ylim()[0]))
    ax.set_title(title)
    ax.grid(alpha=0.3)
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


def _time_unit(t_end):
    """(scale, name) of the time axis: µs below 1 ms, ms below 1 s, else s."""
    return (1e6, "µs") if t_end < 1e-3 else (1e3, "ms") if t_end < 1.0 else (1.0, "s")


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
    scale, unit = _time_unit(max(t[-1], 1e-12))
    fig, ax = plt.subplots(figsize=(7, 3.5), layout="constrained")
    ax.plot(scale * np.asarray(t), 1e3 * np.asarray(w), label="dolfrag (mean across the section)")
    if sdof is not None:
        largest = np.abs(w).max(initial=0.0)
        off_scale = largest > 0 and np.abs(sdof[1]).max() > OFF_SCALE * largest
        ax.plot(scale * sdof[0], 1e3 * sdof[1], "--", label=estimate + (" (off scale)" if off_scale else ""))
        if off_scale:
            ax.set_ylim(-1.1e3 * largest, 1.1e3 * largest)
    if cracked_at is not None:
        ax.axvline(scale * cracked_at, color="k", lw=0.8, ls=":", label="first through-crack")
    ax.set_xlabel(f"time t ({unit})")
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
    scale, unit = _time_unit(max(t[-1], 1e-12))
    fig, ax = plt.subplots(figsize=(7, 3.5), layout="constrained")
    limit = np.abs(image).max(initial=0.0) or 1.0
    mesh = ax.pcolormesh(scale * np.asarray(t), 1e3 * grid, image.T, cmap="RdBu_r",
                         vmin=-limit, vmax=limit, shading="nearest")
    fig.colorbar(mesh, ax=ax, label="velocity across the wall (m/s)")
    ax.set_xlabel(f"time t ({unit})")
    ax.set_ylabel("depth across the thickness (mm)")
    ax.set_title(title)
    fig.savefig(path, dpi=120)
    plt.close(fig)
