"""Rebars: embedded steel bars that carry axial tension only (cables).

A bar is a polyline tied to the cells it crosses. Sampled every ``mesh.size / SAMPLES``,
it becomes one *node* per run of samples in the same cell (the run's mean point), and
one *segment* between consecutive nodes. A node moves with the P1 displacement of its
cell, ``u(X) = sum_i lambda_i(X) u_i`` (lambda the barycentric coordinates), so a
segment spans one or a few facets: when a crack opens there, the jump stretches the
segment, and the bar holds the two sides together. The axial strain of segment j, of
length L_j and direction t_j, is

    eps_j = t_j . (u(X_b) - u(X_a)) / L_j = B_j u,

its force N_j = A_j clip(E_s (eps_j - eps_p,j), 0, f_y) (``cable_force``: no force in
compression, elastic-perfectly plastic in tension), and its nodal forces -B_j^T L_j N_j.
The bars' mass rho_s A L is lumped onto the cell vertices with the same weights lambda_i.
Units: m, Pa, N; in 2D a bar stands for a layer of bars ``spacing`` apart across the
depth, so A is the steel area per metre of depth (m^2/m) and N is N per metre.

Parallel: every rank knows every node (the cell of each sample is decided over all
ranks, by geometry only, so it does not depend on the rank count) and keeps the
*touching* segments, those with a node in an owned cell (the other node's cell is then a
neighbour, held as a ghost): imex computes their forces on the owned rows from current
ghost displacements.
``counted`` segments have their first node in an owned cell: each segment is counted
once, for the energies and for theta's assembly (off-rank rows go through PETSc).
"""
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI

from dolfrag import compat

SAMPLES = 8  # samples per mesh size along a bar: a run per crossed cell, even where it clips a corner


def cable_force(eps, eps_p, E_s, area, f_y=np.inf):
    """Axial force (N, or N/m in 2D) of tension-only elastic-perfectly plastic bars.

    eps, eps_p: total and plastic axial strain (-); E_s: Young's modulus (Pa); area: steel
    area (m^2, or m^2/m in 2D); f_y: yield stress (Pa, inf: elastic). Returns
    (N, eps_p_new, k) with k = dN/deps (N): E_s A while elastic in tension, 0 when slack or
    yielding. Vectorised over bars."""
    sigma_trial = E_s * (eps - eps_p)
    yielding = sigma_trial > f_y
    eps_p_new = np.where(yielding, eps - f_y / E_s, eps_p)
    sigma = np.clip(sigma_trial, 0.0, f_y)
    k = np.where((sigma_trial > 0) & ~yielding, E_s * area, 0.0)
    return area * sigma, eps_p_new, k


def layer_polylines(rebar, geometry, gdim):
    """Polylines (list of (2, gdim) arrays, m) and steel areas (m^2, per metre of depth in
    2D) of the bar layers of a config.Rebar on a rectangle or box: one layer per face in
    ``rebar.faces`` at ``rebar.cover`` (m, face to bar axis), bars along each axis of
    ``rebar.direction`` that is tangent to the face, ``rebar.spacing`` apart (m). In 3D the
    second direction of a face sits one diameter further in, so that the bars cross, and a
    layer has as many bars as fit ``spacing`` apart with at least half a spacing to each
    edge, centred on the face (at least one): the steel per metre away from the edges is
    then A / spacing, as in 2D."""
    extent = np.array([geometry.length, geometry.width, geometry.thickness][:gdim])
    area = np.pi * rebar.diameter**2 / 4
    lines, areas = [], []
    for face in rebar.faces:
        normal_axis, side = divmod(("left", "right", "bottom", "top", "front", "back").index(face), 2)
        along_axes = [a for a in ("xyz".index(c) for c in rebar.direction) if a != normal_axis]
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


def _barycentric(X, p):
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
    inside = _barycentric(X, points[sample]).min(axis=1) if len(cell) else np.empty(0)
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


def nodes(space, lines, size, comm):
    """Sample the bars, decide each sample's cell over all ranks, and merge runs of
    samples in one cell into nodes. Collective."""
    bar, arc, points, ds = _sample(lines, size / SAMPLES)
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
                    np.any(winning_centroid[1:] != winning_centroid[:-1], axis=1)]
    run = np.cumsum(new_run) - 1
    count = np.bincount(run)
    mean = lambda a: np.bincount(run, weights=a) / count  # noqa: E731
    starts = np.flatnonzero(new_run)
    node_x = np.column_stack([mean(points[:, a]) for a in range(space.gdim)])
    run_cell = np.where(local[starts], cell[starts], -1)
    return Nodes(bar[starts], mean(arc), node_x, np.bincount(run, weights=ds), run_cell)


class Rebars:
    """The bars of a case on this rank: strain operator, state and forces.

    B (n, n_local_components) csr: axial strain eps = B u of every local segment; L (m),
    area (m^2, per metre of depth in 2D); E_s, f_y (Pa); eps_p the plastic strain;
    counted (bool, n): see the module docstring (every local segment is touching);
    force_max, peak_force (N, per metre in 2D): the largest axial force on this rank's
    segments at the last committed state, and over the run so far."""

    def __init__(self, space, lines, areas, E_s, f_y, rho_s, size, comm):
        self.space, self.E_s, self.f_y, self.rho_s = space, E_s, (np.inf if f_y is None else f_y), rho_s
        self.comm = comm
        node = self.node = nodes(space, lines, size, comm)
        n_owned = space.n_owned_cells
        a = np.flatnonzero(node.bar[:-1] == node.bar[1:])  # segment j joins nodes a_j, a_j + 1
        b = a + 1
        ca, cb = node.cell[a], node.cell[b]
        owned_a, owned_b = (ca >= 0) & (ca < n_owned), (cb >= 0) & (cb < n_owned)
        keep = owned_a | owned_b
        if np.any(keep & ((ca < 0) | (cb < 0))):
            raise RuntimeError("a rebar segment leaves this rank's cells: its two cells are not neighbours")
        a, b, ca, cb = a[keep], b[keep], ca[keep], cb[keep]
        self.counted = owned_a[keep]
        self._node_area = areas[node.bar]
        chord = node.x[b] - node.x[a]
        self.L = node.arc[b] - node.arc[a]
        t = chord / np.linalg.norm(chord, axis=1)[:, None]
        self.area = areas[node.bar[a]]
        X = space.x
        lam_a = _barycentric(X[space.cell_dofs[ca]], node.x[a])
        lam_b = _barycentric(X[space.cell_dofs[cb]], node.x[b])
        self.comps = np.concatenate([space.components(space.cell_dofs[ca][:, :, None]).reshape(len(a), -1),
                                     space.components(space.cell_dofs[cb][:, :, None]).reshape(len(a), -1)], axis=1)
        coef = np.concatenate([-(lam_a[:, :, None] * t[:, None, :]).reshape(len(a), -1),
                               (lam_b[:, :, None] * t[:, None, :]).reshape(len(a), -1)], axis=1) / self.L[:, None]
        self.coef = coef
        n_comps = len(space.x) * space.gdim
        self.B = sp.csr_matrix((coef.ravel(), self.comps.ravel(), np.arange(0, coef.size + 1, coef.shape[1])),
                               shape=(len(a), n_comps))
        self.BT = self.B.T.tocsr()
        self.eps_p = np.zeros(len(a))
        self.plastic_work = 0.0  # J (J/m in 2D) dissipated on this rank's counted segments
        self.peak_force = self.force_max = 0.0
        self._sigma_old = np.zeros(len(a))

    @property
    def count(self):
        """Number of segments over all ranks. Collective."""
        return self.comm.allreduce(int(self.counted.sum()))

    def add_mass(self, m):
        """Lump the bars' mass onto the local dof components of ``m`` (kg; owned and ghost,
        every node in a local cell: no communication)."""
        node, space = self.node, self.space
        here = node.cell >= 0
        cell = node.cell[here]
        lam = _barycentric(space.x[space.cell_dofs[cell]], node.x[here])
        mass = self.rho_s * self._node_area[here] * node.length[here]
        comps = space.components(space.cell_dofs[cell][:, :, None])  # (n, d+1, gdim)
        np.add.at(m, comps.ravel(), np.repeat((lam * mass[:, None]).ravel(), space.gdim))

    def forces(self, u, commit, counted_only=False):
        """Nodal forces -B^T (L N) (N) of the local segments (the counted ones only, with
        ``counted_only``) at displacement u (all local components), and the tangent
        dN/deps (N). With ``commit``, the plastic strain and the peak force are updated."""
        eps = self.B @ u
        N, eps_p, k = cable_force(eps, self.eps_p, self.E_s, self.area, self.f_y)
        if commit:
            self.plastic_work += float(np.sum((self.L * N * (eps_p - self.eps_p))[self.counted]))
            self.eps_p = eps_p
            self.force_max = N.max(initial=0.0)
            self.peak_force = max(self.peak_force, self.force_max)
        LN = self.L * N * self.counted if counted_only else self.L * N
        return -(self.BT @ LN), k

    def stored_energy(self, u_a, u_b):
        """Elastic energy of the counted segments (J, J/m in 2D), 1/2 L N_a N_b / (E_s A)
        with N at u_a and u_b: the bulk's 1/2 u_{n+1}.K u_n of imex where the bars are in
        tension (u_a = u_b: the energy at one state)."""
        N_a, N_b = (cable_force(self.B @ u, self.eps_p, self.E_s, self.area, self.f_y)[0] for u in (u_a, u_b))
        return float(np.sum((0.5 * self.L * N_a * N_b / (self.E_s * self.area))[self.counted]))

    def stiffness_bound(self, m):
        """An upper bound (1/s^2) of the largest eigenvalue of M^-1 K_bars (Gershgorin on
        the segments' coupling matrix): added to the bulk's omega_max^2 it bounds the
        explicit step's (Weyl). Collective."""
        S = self.B.multiply(np.sqrt(self.E_s * self.area * self.L)[:, None]).tocsr()
        G = (S.multiply(1 / m[None, :]) @ S.T).tocsr()
        local = np.asarray(abs(G).sum(axis=1)).max(initial=0.0)
        return self.comm.allreduce(float(local), op=MPI.MAX)
