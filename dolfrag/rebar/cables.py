"""Rebars: embedded steel bars that carry axial tension only (cables), geometrically exact
or in small strain (``small_strain``, below).

A bar is a polyline tied to the cells it crosses (layout.py): one *node* per crossed
cell, one *segment* between consecutive nodes. A node moves with the P1 displacement of its
cell, ``u(X) = sum_i lambda_i(X) u_i`` (lambda the barycentric coordinates), so a
segment spans one or a few facets: when a crack opens or slides there, the jump stretches
the segment, and the bar holds the two sides together. Segment j (nodes a, b, reference
chord X_b - X_a of length L_j) has the current chord and the engineering strain

    c_j = X_b - X_a + u(X_b) - u(X_a) = c0_j + C_j u,   eps_j = |c_j| / L_j - 1,

exact for any rotation: a crack that slides by delta across a bar stretches it by
sqrt(L^2 + delta^2) - L (the dowel's and the catenary's membrane action), which the
small-strain t.(u_b - u_a) misses. Its force N_j = A_j clip(E_s (eps_j - eps_p,j), 0, f_y)
(``cable_force``: none in compression, elastic-perfectly plastic in tension, a linear
spring in the bar's length while elastic) acts along the current chord, n_j = c_j / |c_j|:
the internal nodal forces are C_j^T (N_j n_j), the gradient of the elastic energy
1/2 L N^2 / (E_s A), with the tangent C_j^T G_j C_j, G = (dN/deps) / L n n^T +
N / |c| (I - n n^T): material and geometric (string) stiffness (``chord_tangent``).
A segment whose accepted strain reaches the rupture strain eps_u (optional; B500 steel:
A_gt >= 5 %, EN 1992-1-1 Annex C) breaks for good: it carries nothing from the next step
on (lagged one step, as the interfaces' damage, so that each step problem stays smooth),
and its elastic energy at that state, 1/2 L N^2 / (E_s A), is dissipated (``dissipated``
= plastic work + the energy released by ruptures).
The bulk beside the bars is linear (small strain): a cell turned by theta moves by the
linearised rotation u = theta e_z x X, which stretches a chord by |c| / L - 1 = sqrt(1 +
theta^2) - 1 ~ theta^2 / 2 where the bulk sees no strain. That spurious stretch reaches the
steel's yield strain f_y / E_s (0.25 % for B500) at theta = 0.07 rad: past it the exact
chords yield bars all along a turning span and stiffen a slab or wall that deflects by more
than about 3.5 % of its span (measured on the ACI 447/370 contest slab: docs/validation.md).
``small_strain`` bars read the strain t0.(C u) / L along their reference direction t0 =
c0 / L instead, with the force along t0: consistent with the bulk and the interfaces (whose
link frames are fixed too), blind to any linearised rotation, without the second-order
stretch of a slid crack or a hanging catenary.
The bars' mass rho_s A L is lumped onto the cell vertices with the same weights lambda_i.
Units: m, Pa, N; in 2D a bar stands for a layer of bars ``spacing`` apart across the
depth, so A is the steel area per metre of depth (m^2/m) and N is N per metre.

Integrators. The explicit scheme (imex) applies N(u_n) n(u_n) and books the work of its
forces on the bulk with the trapezoidal rule along the discrete path (``stored_energy``):
exactly what central differences feed into the kinetic energy, so its balance closes to
round-off through slack, yield and large rotations (for linear elastic bars it is the
bulk's modified energy 1/2 u_{n+1}.K u_n). The implicit scheme (theta) applies a discrete
gradient (Gonzalez 1996): over a step c_n -> c_{n+1} the mean force of the law over the
strain path (``mean_cable_force``) along m = (c_n + c_{n+1}) / (|c_n| + |c_{n+1}|), whose
work N m.(c_{n+1} - c_n) = N L (eps_{n+1} - eps_n) is exactly the change of the elastic
energy (``elastic_energy``) plus the plastic work (``plastic_work``, L N d(eps_p) at the
accepted states), whatever the step: the bars neither create nor destroy energy, and
their tangent (``step_blocks``) is the derivative of that force in c_{n+1}. The force at
u_theta instead (the trapezoidal rule's midpoint) created 412 J, 1 % of the work, in the
last 3 ms of wall-bending-clamped at theta = 1/2, where loose pieces hang on bars that go
slack and taut (measured).

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
from numba import njit

from dolfrag import compat
from dolfrag.rebar.layout import barycentric, nodes


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


def chord_strain(chord0, dc, L, small_strain=False):
    """Engineering strain |c| / L - 1 (-) of chords c = chord0 + dc (m, (n, d)) of reference
    length L (m), and c and |c| (m). Vectorised.

    small_strain: the strain t0.dc / L along the reference direction t0 = chord0 / L
    instead, returned with the reference chords and lengths (the force keeps direction t0)."""
    if small_strain:
        return np.einsum("ji,ji->j", chord0, dc) / L**2, chord0, L
    c = chord0 + dc
    ell = np.linalg.norm(c, axis=1)
    # |c| - L = (2 c0.dc + dc.dc) / (|c| + L): no cancellation, so a strain of 1e-12
    # keeps its own relative precision (|c| / L - 1 would carry 1e-16 absolute noise,
    # the whole force of the first steps of a slow load)
    stretch = np.einsum("ji,ji->j", 2 * chord0 + dc, dc) / (ell + L)
    return stretch / L, c, ell


def _ramp_mean(p, q, a):
    """Mean of max(s - a, 0) over s in [p, q] (either order), and its derivative in q.
    Straddling a kink the mean is (top - a)^2 / (2 |q - p|), with |q - p| >= top - a: no
    division by a vanishing interval, and p = q gives the value at p."""
    lo, hi = np.minimum(p, q), np.maximum(p, q)
    width = np.where(hi > lo, hi - lo, 1.0)
    mean = np.where(lo >= a, 0.5 * (p + q) - a, np.where(hi <= a, 0.0, (hi - a) ** 2 / (2 * width)))
    slope_q_top = (hi - a) / width - (hi - a) ** 2 / (2 * width**2)  # q is the top
    slope_q_bottom = (hi - a) ** 2 / (2 * width**2)  # q is the bottom
    slope = np.where(lo >= a, 0.5, np.where(hi <= a, 0.0, np.where(q >= p, slope_q_top, slope_q_bottom)))
    return mean, slope


def mean_cable_force(eps_a, eps_b, eps_p, E_s, area, f_y=np.inf):
    """Mean axial force (N) of cable_force over a step's strain path eps_a -> eps_b (the
    path is monotone within the step, the plastic strain eps_p its start's), and its
    derivative in eps_b (N). Along the path N(s) = E_s A (ramp(s - eps_p) - ramp(s - eps_y)),
    eps_y = eps_p + f_y / E_s, so the mean is exact: L (eps_b - eps_a) times it is the work
    of the bar over the step, elastic energy change plus plastic dissipation (the
    module docstring). Vectorised over bars."""
    k = E_s * area
    N, dN = _ramp_mean(eps_a, eps_b, eps_p)
    if np.isfinite(f_y):
        N_y, dN_y = _ramp_mean(eps_a, eps_b, eps_p + f_y / E_s)
        N, dN = N - N_y, dN - dN_y
    return k * N, k * dN


def chord_tangent(m_hat, n_hat, sigma, N, dN, L, small_strain=False):
    """d(N m)/dc (N/m, (n, d, d)) of a force N along m = s / sigma, where s = c_a + c and
    sigma = |c_a| + |c| for a chord c (m) moving from c_a, n = c / |c|, and N depends on c
    through the strain |c| / L - 1 with dN = dN/deps (N): material (dN / L) m n^T plus
    geometric (N / sigma)(I - m n^T), the string stiffness that resists a turn of the chord.
    With c_a = c (s = 2 c, m = n) it is half the tangent of N(eps) n at c; the tangent
    itself is chord_tangent(n, n, |c|, N, k, L). small_strain: the chords keep their
    reference direction (m = n = t0), so only the material part (dN / L) t0 t0^T remains.
    Vectorised over bars."""
    mn = m_hat[:, :, None] * n_hat[:, None, :]
    if small_strain:
        return (dN / L)[:, None, None] * mn
    eye = np.eye(n_hat.shape[1])
    return (dN / L)[:, None, None] * mn + (N / sigma)[:, None, None] * (eye - mn)


@dataclass
class CableState:
    """The local segments at one displacement: strains eps (-), unit chords n_hat (n, d),
    chord lengths ell (m), axial forces N (N, N/m in 2D), tangents k = dN/deps (N) and the
    plastic strains eps_p a step ending there would accept."""
    eps: np.ndarray
    n_hat: np.ndarray
    ell: np.ndarray
    N: np.ndarray
    k: np.ndarray
    eps_p: np.ndarray


@dataclass
class CableStep:
    """The local segments over a step from the accepted state (chords c_a) to an end (c):
    the mean force N (N) over the strain path and its derivative dN (N) in the end strain,
    the direction m_hat = (c_a + c) / sigma (n, d), sigma = |c_a| + |c| (m), and the end's
    CableState."""
    N: np.ndarray
    dN: np.ndarray
    m_hat: np.ndarray
    sigma: np.ndarray
    end: CableState


class Rebars:
    """The bars of a case on this rank: chord kinematics, state and forces.

    C (n d, n_local_components) csr: chord displacements of the local segments, c = c0 + C u
    (rows segment-major, then axis); weights (n, 2(d+1)): C's coefficient of each vertex of
    cell a, then cell b (-lambda_a, lambda_b); comps (n, 2(d+1) d): those vertices' flat
    components; L (m) reference chord lengths; area (m^2, per metre of depth in 2D); E_s,
    f_y (Pa); eps_u (-) the rupture strain; eps_p the accepted plastic strain; ruptured
    (bool, n) the broken segments; counted (bool, n): see the module docstring (every local
    segment is touching); force_max, peak_force (N, per metre in 2D): the largest axial
    force on this rank's segments at the last accepted state, and over the run so far."""

    # what a checkpoint keeps
    STATE = ("eps_p", "ruptured", "plastic_work", "rupture_work", "peak_force", "force_max", "_work", "_u_last",
             "_f_last")

    def __init__(self, space, lines, areas, E_s, f_y, rho_s, size, comm, eps_u=None, small_strain=False):
        self.space, self.E_s, self.f_y, self.rho_s = space, E_s, (np.inf if f_y is None else f_y), rho_s
        self.eps_u = np.inf if eps_u is None else eps_u
        self.small_strain = small_strain
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
        n, d = len(a), space.gdim
        self.d = d
        self.counted = owned_a[keep]
        self._node_area = areas[node.bar]
        self.x_a, self.cell_a = node.x[a], ca  # each segment's first node (m) and its cell (local)
        self.chord0 = node.x[b] - node.x[a]
        self.L = np.linalg.norm(self.chord0, axis=1)
        self.area = areas[node.bar[a]]
        X = space.x
        self.weights = np.column_stack([-barycentric(X[space.cell_dofs[ca]], node.x[a]),
                                        barycentric(X[space.cell_dofs[cb]], node.x[b])])
        per_cell = (d + 1) * d  # explicit: a rank may hold no segment
        self.comps = np.concatenate([space.components(space.cell_dofs[ca][:, :, None]).reshape(n, per_cell),
                                     space.components(space.cell_dofs[cb][:, :, None]).reshape(n, per_cell)], axis=1)
        shape = (n, 2 * (d + 1), d)
        rows = np.broadcast_to(np.arange(n)[:, None, None] * d + np.arange(d), shape)
        self.C = sp.csr_matrix((np.broadcast_to(self.weights[:, :, None], shape).ravel(),
                                (rows.ravel(), self.comps.ravel())), shape=(n * d, len(X) * d))
        self.CT = self.C.T.tocsr()
        self.eps_p = np.zeros(n)
        self.ruptured = np.zeros(n, dtype=bool)
        # J (J/m in 2D) dissipated on this rank's counted segments: by yield, by ruptures
        self.plastic_work = self.rupture_work = 0.0
        self.peak_force = self.force_max = 0.0
        self._own = slice(0, space.n_owned_dofs * d)
        # the explicit scheme's work booking (stored_energy): owned rows at the last commit,
        # kept on the owned components the bars touch (the forces are zero elsewhere)
        self._work = 0.0
        self._u_last, self._f_last = np.zeros(self._own.stop), np.zeros(self._own.stop)
        self._bar = np.unique(self.comps[self.comps < self._own.stop])

    @property
    def count(self):
        """Number of segments over all ranks. Collective."""
        return self.comm.allreduce(int(self.counted.sum()))

    @property
    def mass(self):
        """The bars' mass (kg, kg/m in 2D), rho_s A L over every bar (each rank knows all)."""
        return self.rho_s * float(self._node_area @ self.node.length)

    @property
    def ruptures(self):
        """Number of ruptured segments over all ranks. Collective."""
        return self.comm.allreduce(int((self.ruptured & self.counted).sum()))

    @property
    def dissipated(self):
        """Energy (J, J/m in 2D) this rank's counted segments dissipated: plastic work and
        the elastic energy released by ruptures."""
        return self.plastic_work + self.rupture_work

    def segments(self, u, scale=1.0):
        """The two ends (n, 2, d) (m) of every local segment at displacement u (all local
        components, m) magnified ``scale`` times: each node moved with its cell."""
        n, k = len(self.L), self.d + 1
        U = scale * u[self.comps].reshape(n, 2 * k, self.d)
        start = self.x_a - np.einsum("jc,jci->ji", self.weights[:, :k], U[:, :k])  # weights of a are -lambda
        end = self.x_a + self.chord0 + np.einsum("jc,jci->ji", self.weights[:, k:], U[:, k:])
        return np.stack([start, end], axis=1)

    def add_mass(self, m):
        """Lump the bars' mass onto the local dof components of ``m`` (kg; owned and ghost,
        every node in a local cell: no communication)."""
        node, space = self.node, self.space
        here = node.cell >= 0
        cell = node.cell[here]
        lam = barycentric(space.x[space.cell_dofs[cell]], node.x[here])
        mass = self.rho_s * self._node_area[here] * node.length[here]
        comps = space.components(space.cell_dofs[cell][:, :, None])  # (n, d+1, gdim)
        np.add.at(m, comps.ravel(), np.repeat((lam * mass[:, None]).ravel(), space.gdim))

    def strain(self, u):
        """Strain (-) of every local segment at displacement u (m), and the chords c (n, d) and
        their lengths |c| (m): chord_strain's, exact or small strain."""
        return chord_strain(self.chord0, (self.C @ u).reshape(-1, self.d), self.L, self.small_strain)

    def state(self, u):
        """CableState of the local segments at displacement u (all local components, m),
        from the accepted plastic strain."""
        eps, c, ell = self.strain(u)
        N, eps_p, k = cable_force(eps, self.eps_p, self.E_s, self.area, self.f_y)
        N, k = np.where(self.ruptured, 0.0, N), np.where(self.ruptured, 0.0, k)
        n_hat = np.divide(c, ell[:, None], out=np.zeros_like(c), where=ell[:, None] > 0)  # collapsed: slack
        return CableState(eps, n_hat, ell, N, k, eps_p)

    def step(self, u_a, u_b):
        """CableStep of the local segments from u_a (the accepted state's displacement) to
        u_b (all local components, m)."""
        eps_a, c_a, ell_a = self.strain(u_a)
        end = self.state(u_b)
        N, dN = mean_cable_force(eps_a, end.eps, self.eps_p, self.E_s, self.area, self.f_y)
        N, dN = np.where(self.ruptured, 0.0, N), np.where(self.ruptured, 0.0, dN)
        sigma = ell_a + end.ell
        s = c_a + end.n_hat * end.ell[:, None]
        m_hat = np.divide(s, sigma[:, None], out=np.zeros_like(s), where=sigma[:, None] > 0)
        return CableStep(N, dN, m_hat, sigma, end)

    def step_forces(self, step, counted_only=False):
        """Nodal forces -C^T (N m) (N) the local segments (the counted ones only, with
        ``counted_only``) put on the bulk over a CableStep: the discrete gradient of the
        module docstring."""
        N = step.N * self.counted if counted_only else step.N
        return -(self.CT @ (N[:, None] * step.m_hat).ravel())

    def forces(self, u, commit):
        """Nodal forces -C^T (N n) (N) the local segments put on the bulk at displacement u
        (all local components), and their CableState (``state``'s, compiled: _cable_forces):
        the explicit scheme's. ``commit`` is its call once per step at u_n: the state is
        accepted and the step's work booked (stored_energy)."""
        n = len(self.L)
        state = CableState(np.empty(n), np.empty((n, self.d)), np.empty(n), np.empty(n), np.empty(n), np.empty(n))
        f = np.empty_like(u)
        _cable_forces(self.comps, self.weights, self.chord0, self.L, self.area, float(self.E_s), float(self.f_y),
                      self.eps_p, self.ruptured, self.small_strain, u, state.eps, state.n_hat, state.ell, state.N,
                      state.k, state.eps_p, f)
        if commit:
            self.accept(state)
            self._work += _book_work(self._bar, f, u, self._f_last, self._u_last)
        return f, state

    def accept(self, state):
        """Make ``state`` (the end of a step) the accepted one: plastic strain, plastic
        work L N d(eps_p) of the counted segments, largest forces; the segments whose strain
        reached eps_u rupture, releasing their elastic energy there."""
        plastic, rupture, self.force_max = _accept(self.L, self.area, float(self.E_s), float(self.eps_u), self.counted,
                                                   state.eps, state.N, state.eps_p, self.eps_p, self.ruptured)
        self.plastic_work += plastic
        self.rupture_work += rupture
        self.peak_force = max(self.peak_force, self.force_max)

    def work(self, step, du):
        """Work (J, J/m in 2D) of the counted segments' forces N m over a CableStep whose
        displacement increment is du (all local components, m): sum N m.(C du), which is
        N L (eps_b - eps_a) for each."""
        dc = (self.C @ du).reshape(-1, self.d)
        return float(np.sum((step.N * np.einsum("ji,ji->j", step.m_hat, dc))[self.counted]))

    def step_blocks(self, step):
        """Tangent blocks C_j^T (d(N m)/dc) C_j (N/m, (n_counted, 2(d+1) d, 2(d+1) d), rows
        and columns ordered as comps) of the counted segments' step forces in the end
        displacement: not symmetric (chord_tangent)."""
        c, end = self.counted, step.end
        G = chord_tangent(step.m_hat[c], end.n_hat[c], step.sigma[c], step.N[c], step.dN[c], self.L[c],
                          self.small_strain)
        w = self.weights[c]
        n, m = w.shape
        return np.einsum("jv,jw,jik->jviwk", w, w, G).reshape(n, m * self.d, m * self.d)

    def elastic_energy(self, u):
        """Elastic energy 1/2 L N^2 / (E_s A) of the counted segments at u (J, J/m in 2D),
        with the accepted plastic strain and ruptures."""
        N = self.state(u).N
        return float(np.sum((0.5 * self.L * N * N / (self.E_s * self.area))[self.counted]))

    def stored_energy(self, u_a, u_b):
        """The explicit scheme's bar energy at the mid-step t_{n+1/2} (J, J/m in 2D): the
        work of the bars' internal forces f on the bulk, trapezoidal along the path
        sum_k (f_{k-1} + f_k).(u_k - u_{k-1}) / 2 up to u_a = u_n (the last ``commit``),
        plus f_n.(u_b - u_a) / 2 to u_b = u_{n+1}, less the dissipated energy: this rank's owned
        rows. Central differences give the kinetic energy exactly these increments,
        f_n.(u_{n+1} - u_{n-1}) / 2, so the balance closes to round-off; for elastic bars
        in one regime this is the modified energy 1/2 u_{n+1}.K u_n, and it stays within
        O(h^2) of elastic_energy."""
        own = self._own
        return self._work + 0.5 * self._f_last @ (u_b[own] - u_a[own]) - self.dissipated

    kinetic_energy = 0.0  # J: the bars' mass is the bulk's (add_mass)

    def explicit_step(self, u, h):
        """The explicit step's forces on the bulk at u (``forces``, committed; h, s, is not
        needed: the bars move with the bulk)."""
        return self.forces(u, commit=True)[0]

    def spring_terms(self, to_global, n_concrete):
        """The bars' springs for the stable step (stable_step.coupled_omega2): the counted
        segments' global components (s, 2(d+1), d) and factors (stiffness_factors), and no
        nodes of their own (empty ids and masses; n_concrete unused)."""
        S = self.stiffness_factors()
        comps = to_global(self.comps[self.counted]).reshape(-1, S.shape[1], self.d)
        return comps, S, np.empty(0, np.int64), np.empty(0)

    def stiffness_factors(self):
        """S (n_counted, 2(d+1)): sqrt(E_s A / L) times the barycentric weights of each
        counted segment, so that sum_j (E_s A / L)_j C_j^T C_j is sum_j S_j S_j^T on each axis
        (the bound of the bars' tangent in every state, stiffness_bound)."""
        return np.sqrt(self.E_s * self.area / self.L)[self.counted, None] * self.weights[self.counted]

    def stiffness_bound(self, m, index_map):
        """An upper bound (1/s^2) of the largest eigenvalue of M^-1 K_bars at any state,
        to add to the bulk's omega_max^2 (Weyl) for the explicit step. m: the lumped mass
        of every local dof component (kg); index_map: the space's dof index map. Collective.

        G_j <= (E_s A / L) I in every state (the material part is E_s A / L or 0 along n,
        the geometric N / |c| < E_s A / L across it), so K_bars <= sum_j (E_s A / L)
        C_j^T C_j: d copies, one per axis, of a scalar operator whose eigenvalues Gershgorin
        bounds on the segments' coupling matrix. Two segments are coupled through the dofs
        they share, which may sit on different ranks: the matrix is formed on rank 0 from
        every rank's counted segments, so the bound does not depend on the partition."""
        first_axis = self.comps.reshape(len(self.L), 2 * (self.d + 1), self.d)[self.counted][:, :, 0]
        S = self.stiffness_factors()
        dofs = compat.global_indices(index_map, first_axis.ravel() // self.d)
        parts = self.comm.gather((dofs, S.ravel(), m[first_axis.ravel()]), root=0)
        bound = None
        if self.comm.rank == 0:
            dofs, S, m_dofs = (np.concatenate(p) for p in zip(*parts))
            cols, column = np.unique(dofs, return_inverse=True)
            width = first_axis.shape[1]
            S = sp.csr_matrix((S, column, np.arange(0, len(S) + 1, width)), shape=(len(S) // width, len(cols)))
            m_cols = np.zeros(len(cols))
            m_cols[column] = m_dofs
            G = (S.multiply(1 / m_cols[None, :]) @ S.T).tocsr()
            bound = float(np.asarray(abs(G).sum(axis=1)).max(initial=0.0))
        return self.comm.bcast(bound, root=0)


# The explicit scheme's bar forces segment by segment, compiled: numpy's (the chords by a
# sparse product, the norm, the law, the unit chords and the transposed product, each a
# pass with its temporaries) cost 106 us of a 1.6 ms wall-bending-clamped step for its
# 198 segments. ``state`` and ``cable_force`` above are what they follow
# (tests/test_rebar.py).

@njit(cache=True, error_model="numpy")
def _cable_forces(comps, weights, chord0, L, area, E_s, f_y, eps_p, ruptured, small_strain, u, eps, n_hat, ell, N, k,
                  eps_p_new, f):
    """Per segment j, as Rebars.state: the chord c = chord0 + C_j u from its vertices'
    components comps[j] and weights[j], |c| (ell), the strain (eps), cable_force's N, k and
    plastic strain (eps_p_new; N = k = 0 where ruptured), the unit chord (n_hat); f (as u)
    = -C^T (N n_hat). small_strain: chord_strain's, c = chord0."""
    n, m = weights.shape
    d = chord0.shape[1]
    f[:] = 0.0
    c = np.empty(d)
    for j in range(n):
        square, stretch = 0.0, 0.0
        for i in range(d):
            dc = 0.0
            for v in range(m):
                dc += weights[j, v] * u[comps[j, v * d + i]]
            if small_strain:
                c[i] = chord0[j, i]
                stretch += chord0[j, i] * dc
            else:
                c[i] = chord0[j, i] + dc
                stretch += (2 * chord0[j, i] + dc) * dc
            square += c[i] * c[i]
        ell[j] = np.sqrt(square)
        # exact: (|c|^2 - L^2) / (|c| + L) / L, no cancellation (see chord_strain); small
        # strain: t0.dc / L = (chord0.dc) / L^2, with |c| = L
        eps[j] = stretch / L[j] / L[j] if small_strain else stretch / (ell[j] + L[j]) / L[j]
        sigma_trial = E_s * (eps[j] - eps_p[j])
        yielding = sigma_trial > f_y
        eps_p_new[j] = eps[j] - f_y / E_s if yielding else eps_p[j]
        N[j] = 0.0 if ruptured[j] else area[j] * min(max(sigma_trial, 0.0), f_y)
        k[j] = E_s * area[j] if sigma_trial > 0 and not yielding and not ruptured[j] else 0.0
        for i in range(d):
            n_hat[j, i] = c[i] / ell[j] if ell[j] > 0 else 0.0
            for v in range(m):
                f[comps[j, v * d + i]] -= weights[j, v] * N[j] * n_hat[j, i]


@njit(cache=True, error_model="numpy")
def _accept(L, area, E_s, eps_u, counted, eps, N, eps_p_new, eps_p, ruptured):
    """Rebars.accept segment by segment: eps_p (n,) takes eps_p_new, and the segments whose
    strain eps reached eps_u rupture (ruptured, in place). Returns the plastic work
    L N d(eps_p) and the released elastic energy 1/2 L N^2 / (E_s A) of the rupturing
    segments, both over the counted ones (J, J/m in 2D), and the largest N (N, 0 if none)."""
    plastic, rupture, largest = 0.0, 0.0, 0.0
    for j in range(len(L)):
        if counted[j]:
            plastic += L[j] * N[j] * (eps_p_new[j] - eps_p[j])
        eps_p[j] = eps_p_new[j]
        if eps[j] >= eps_u and not ruptured[j]:
            if counted[j]:
                rupture += 0.5 * L[j] * N[j] ** 2 / (E_s * area[j])
            ruptured[j] = True
        largest = max(largest, N[j])
    return plastic, rupture, largest


@njit(cache=True, error_model="numpy")
def _book_work(bar, f, u, f_last, u_last):
    """The work of the bars' internal forces -f (N) over the step from u_last to u (m),
    trapezoidal, 1/2 (f_last - f).(u - u_last), on the components ``bar``; f_last, u_last
    then take -f and u there. Returns the work (J, J/m in 2D)."""
    work = 0.0
    for c in bar:
        work += 0.5 * (f_last[c] - f[c]) * (u[c] - u_last[c])
        f_last[c], u_last[c] = -f[c], u[c]
    return work


def warm():
    """Compile the forces, accept and the work booking (2D and 3D) into numba's cache on
    one segment of each."""
    for d in (2, 3):
        m = 2 * (d + 1)
        comps = np.arange(m * d).reshape(1, -1)
        out = [np.zeros(1), np.zeros((1, d)), np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1)]
        _cable_forces(comps, np.ones((1, m)), np.ones((1, d)), np.ones(1), np.ones(1), 1.0, np.inf, np.zeros(1),
                      np.zeros(1, bool), False, np.zeros(m * d), *out, np.zeros(m * d))
    _accept(np.ones(1), np.ones(1), 1.0, np.inf, np.ones(1, bool), *(np.zeros(1) for _ in range(4)), np.zeros(1, bool))
    _book_work(np.zeros(1, dtype=np.int64), *(np.zeros(1) for _ in range(4)))
