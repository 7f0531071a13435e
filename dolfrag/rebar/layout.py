"""Where the rebars are: bar layers near faces, and the nodes that tie them to the cells
they cross (rebar.py's module docstring).

A bar is sampled every ``mesh.size / SAMPLES``; the cell of each sample is decided over all
ranks by geometry only (so it does not depend on the rank count), and a run of samples in
one cell becomes one node (the run's mean point). Units: m; areas m^2 (m^2/m in 2D).
"""
from dataclasses import dataclass

import numpy as np

from dolfrag import bunker, compat

SAMPLES = 8  # samples per mesh size along a bar: a run per crossed cell, even where it clips a corner


def layer_polylines(rebar, geometry, gdim):
    """Polylines (list of (2, gdim) arrays, m) and steel areas (m^2, per metre of depth in
    2D) of the bar layers of a case.Rebar on a rectangle or box: one layer per face in
    ``rebar.faces`` at ``rebar.cover`` (m, face to bar axis), bars along each axis of
    ``rebar.direction`` that is tangent to the face, ``rebar.spacing`` apart (m). In 3D the
    second direction of a face sits one diameter further in, so that the bars cross, and a
    layer has as many bars as fit ``spacing`` apart with at least half a spacing to each
    edge, centred on the face (at least one): the steel per metre away from the edges is
    then A / spacing, as in 2D. direction "both": the two axes along each face. A bunker's
    layers: bunker.rebar_polylines."""
    if geometry.kind == "bunker":
        return bunker.rebar_polylines(rebar, geometry)
    extent = np.array([geometry.length, geometry.width, geometry.thickness][:gdim])
    area = np.pi * rebar.diameter**2 / 4
    lines, areas = [], []
    for face in rebar.faces:
        normal_axis, side = divmod(("left", "right", "bottom", "top", "front", "back").index(face), 2)
        axes = range(gdim) if rebar.direction == "both" else ("xyz".index(c) for c in rebar.direction)
        along_axes = [a for a in axes if a != normal_axis]
        for layer, along in enumerate(along_axes):
            depth = rebar.cover + layer * rebar.diameter
            level = extent[normal_axis] - depth if side else depth
            if gdim == 2:
                positions, bar_area = [None], area / rebar.spacing
            else:
                across = 3 - normal_axis - along
                # 1e-9: an extent that is a whole number of spacings keeps its last bar
                count = max(1, int(np.floor(extent[across] / rebar.spacing + 1e-9)))
                positions = extent[across] / 2 + (np.arange(count) - (count - 1) / 2) * rebar.spacing
                bar_area = area
            for position in positions:
                ends = np.zeros((2, gdim))
                ends[:, normal_axis] = level
                ends[:, along] = (0.0, extent[along])
                if position is not None:
                    ends[:, across] = position
                lines.append(ends)
                areas.append(bar_area)
    return lines, np.array(areas)


def barycentric(X, p):
    """Barycentric coordinates (n, gdim+1) of points p (n, gdim) in simplices X (n, gdim+1, gdim)."""
    T = np.swapaxes(X[:, 1:] - X[:, :1], 1, 2)
    lam = np.linalg.solve(T, (p - X[:, 0])[:, :, None])[:, :, 0]
    return np.column_stack([1 - lam.sum(axis=1), lam])


def _sample(lines, spacing):
    """Samples along the polylines, about ``spacing`` (m) apart: bar index, arc length (m),
    point (m) and share of the bar's length (m) of each."""
    bar, arc, points, ds = [], [], [], []
    for k, line in enumerate(lines):
        lengths = np.linalg.norm(np.diff(line, axis=0), axis=1)
        s_vertices = np.r_[0.0, np.cumsum(lengths)]
        n = max(2, int(np.ceil(s_vertices[-1] / spacing)))
        s = (np.arange(n) + 0.5) * s_vertices[-1] / n
        bar.append(np.full(n, k))
        arc.append(s)
        ds.append(np.full(n, s_vertices[-1] / n))
        points.append(np.column_stack([np.interp(s, s_vertices, line[:, a]) for a in range(line.shape[1])]))
    return tuple(np.concatenate(a) for a in (bar, arc, points, ds))


def _locate(space, points, size):
    """For each point, the local cell that holds it best (largest smallest barycentric
    coordinate, ties to the smaller centroid), that coordinate, and the cell centroid.
    -1 / -inf where no local cell holds it. Not collective."""
    msh = space.mesh
    tdim = msh.topology.dim
    tree = compat.bounding_box_tree(msh, tdim)
    padded = np.zeros((len(points), 3))
    padded[:, :space.gdim] = points
    candidates = compat.point_candidates(tree, padded)
    sample = np.repeat(np.arange(len(points)), np.diff(candidates.offsets))
    cell = candidates.array.astype(np.int64)
    X = space.x[space.cell_dofs[cell]]
    inside = barycentric(X, points[sample]).min(axis=1) if len(cell) else np.empty(0)
    centroid = X.mean(axis=1)
    # the best candidate last in each sample's group: sort by sample, then inside, then -centroid
    order = np.lexsort((*(-np.round(centroid / size, 9)).T[::-1], inside, sample))
    last = np.r_[sample[order][1:] != sample[order][:-1], True] if len(order) else np.empty(0, bool)
    best = order[last]
    chosen = np.full(len(points), -1)
    score = np.full(len(points), -np.inf)
    where = np.full((len(points), space.gdim), np.nan)
    chosen[sample[best]], score[sample[best]], where[sample[best]] = cell[best], inside[best], centroid[best]
    return chosen, score, where


@dataclass
class Nodes:
    """Bar nodes, the same on every rank: bar index, arc length (m), point (m), tributary
    length (m), and the local cell holding each (-1 where it is not on this rank)."""
    bar: np.ndarray
    arc: np.ndarray
    x: np.ndarray
    length: np.ndarray
    cell: np.ndarray


def nodes(space, lines, size, comm, samples=SAMPLES, merge=True):
    """Sample the bars every ``size / samples`` (m), decide each sample's cell over all
    ranks, and (``merge``) merge runs of samples in one cell into nodes; without it every
    sample is a node. Collective."""
    bar, arc, points, ds = _sample(lines, size / samples)
    cell, score, centroid = _locate(space, points, size)
    # every rank's best guess; the winner is decided by geometry alone, as on one rank
    scores = np.array(comm.allgather(score))
    centroids = np.array(comm.allgather(centroid))
    keys = np.round(np.nan_to_num(centroids, nan=np.inf) / size, 9)
    rank_order = np.lexsort((*(-keys).transpose(2, 0, 1)[::-1], scores), axis=0)
    winner = rank_order[-1]
    best_score = scores[winner, np.arange(len(points))]
    if np.any(best_score < -1e-9):
        lost = points[np.argmin(best_score)]
        raise ValueError(f"a rebar point at {np.round(lost, 6).tolist()} m lies outside the mesh")
    winning_centroid = centroids[winner, np.arange(len(points))]
    local = np.all(np.abs(centroid - winning_centroid) < 1e-9 * size, axis=1)
    # runs: consecutive samples of one bar in the same cell (one centroid)
    new_run = np.r_[True, (bar[1:] != bar[:-1]) |
                    np.any(winning_centroid[1:] != winning_centroid[:-1], axis=1) | (not merge)]
    run = np.cumsum(new_run) - 1
    count = np.bincount(run)
    mean = lambda a: np.bincount(run, weights=a) / count  # noqa: E731
    starts = np.flatnonzero(new_run)
    node_x = np.column_stack([mean(points[:, a]) for a in range(space.gdim)])
    run_cell = np.where(local[starts], cell[starts], -1)
    return Nodes(bar[starts], mean(arc), node_x, np.bincount(run, weights=ds), run_cell)
