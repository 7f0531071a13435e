"""Bond-slip between the bars and the concrete (``rebar.bond = "fib2010"``).

Why. With perfect bond (cables.py) a bar node moves with its cell, so a bar segment about one
cell long carries a crack's whole opening: across a crack the bar is as stiff as E_s A / h,
and the concrete beside the crack takes the bar's force back at once. Nothing but the mesh
then sets how far apart cracks form, and the cracking of a reinforced member grows as the
mesh is refined (docs/validation.md). A real bar slips along the concrete: its force passes
back into the concrete over a transfer length set by the bond strength, and no new crack
forms closer than that.

The model. The bars get nodes of their own, one about every mesh.size along each bar, with
displacement u_s (m), velocity v_s (m/s) and mass rho_s A l (l the node's share of the bar),
integrated by central differences like the bulk. Consecutive nodes are joined by bar
segments, geometrically exact as the cables of cables.py (force along the current chord,
rupture at eps_u) but elastic-perfectly plastic in compression as in tension (``bar_force``):
a bar held in concrete carries compression, and a tension-only segment between two light
nodes goes slack and taut again within a few steps, a kink that explicit steps cross with
an error of one sign each time (measured: the bars' booked energy fell 1.1 kJ below their
elastic energy and dissipation in a cracking wall). Node i lies
at the point X_i of a cell (barycentric weights lambda_j) and is held to the concrete there
by the bond: with the slip vector s = u_s,i - u_c(X_i),

    F_i = -p l tau   on the node,   -lambda_j F_i on vertex j of its cell,

p (m) the bar's perimeter, 4 A / diameter (per metre of depth in 2D, as A), and tau (Pa, a
vector) the bond stress: elastic, k_0 (s - s_p), inside a circle of radius the fib Model
Code 2010 bond-slip envelope (eq. 6.1-1, ``envelope``) at the largest |s| reached, and
returned radially onto it otherwise (``bond_stress``), s_p the plastic slip. Along the bar
this is the Model Code's law: on the envelope while the slip grows, unloading elastically, a
reversed slip yielding at minus the envelope of the largest slip reached. Across the bar the
same strength stands for the concrete's bearing on the bar (its dowel action), which the
Model Code does not give; the bearing strength of the concrete under a bar, about f_cm
over a width of one diameter, is of the same size as tau_max over its perimeter (assumed).
The law has a potential (1/2 |tau|^2 / k_0, stored) and an associated flow, so its work over
a step is that potential's change plus p l times the mean stress on the plastic slip
(``plastic_slip_work``), which is dissipated; a tangent-based split (a slip along the bar's
current direction) has no potential under rotation and was measured to create energy in a
wall whose pieces turn on the bars.

Parallel. Every rank holds every node and integrates all of them alike. A node's bond force
is computed by the rank owning its cell (whose displacements it holds current) and summed
over the ranks: one reduction a step, exact, since one rank gives each entry. The cables
between nodes are computed on every rank. So the bars' state is the same on every rank,
whatever the partition. The energies of the nodes and cables are counted on rank 0, the
bond's on the rank computing it.

Energies. As for the perfectly bonded bars, the stored energy is the work of the bars' and
bond's forces booked with the trapezoidal rule along the discrete path (cables.py's
``stored_energy``), on the concrete's components and on the nodes' own, so that with the
nodes' kinetic energy the balance closes to round-off.

Units: m, s, kg, Pa, N (per metre of depth in 2D).
"""
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from dolfrag.rebar.cables import _accept, _book_work, chord_strain
from dolfrag.rebar.layout import barycentric, nodes


@dataclass(frozen=True)
class BondLaw:
    """The fib Model Code 2010 bond-slip law of ribbed bars, pull-out failure, good bond
    conditions (Table 6.1-1): tau_max (Pa), 2.5 sqrt(f_cm) there (concrete.bond_strength); s1, s2 (m) the ends of the
    rising branch and of the plateau; s3 (m) the clear rib spacing, where the bond has fallen
    to its residual ``residual`` x tau_max; alpha (-) the rising branch's exponent.
    elastic_slip (m): where the elastic line k_0 s meets the envelope, whose power law has
    an infinite slope at zero slip."""
    tau_max: float
    s3: float
    s1: float = 1.0e-3
    s2: float = 2.0e-3
    alpha: float = 0.4
    residual: float = 0.4
    elastic_slip: float = 1.0e-5

    @property
    def k_0(self):
        """The elastic stiffness (Pa/m): the envelope's secant at elastic_slip."""
        return float(envelope(self, self.elastic_slip)) / self.elastic_slip


def envelope(law, slip):
    """Bond stress (Pa) of the fib Model Code 2010 envelope at the slip |slip| (m):
    tau_max (s/s1)^alpha up to s1, tau_max to s2, linear to tau_f = residual x tau_max at s3,
    tau_f beyond. Vectorised."""
    s = np.abs(slip)
    rising = law.tau_max * (np.minimum(s, law.s1) / law.s1) ** law.alpha
    fall = np.clip((s - law.s2) / (law.s3 - law.s2), 0.0, 1.0)
    return np.where(s <= law.s1, rising, law.tau_max * (1.0 - (1.0 - law.residual) * fall))


def bond_stress(law, slip, slip_p, slip_max):
    """Return map of the bond: the stress tau (Pa, (n, d)) at the slip vectors ``slip`` (m,
    (n, d)) from the accepted plastic slips slip_p (m, (n, d)) and largest slips reached
    slip_max (m, (n,)), and the slip_p and slip_max a step ending there would accept: the
    elastic trial k_0 (slip - slip_p) scaled back radially onto the envelope at the largest
    slip reached."""
    reached = np.maximum(slip_max, np.linalg.norm(slip, axis=-1))
    limit = envelope(law, reached)
    trial = law.k_0 * (slip - slip_p)
    size = np.linalg.norm(trial, axis=-1)
    scale = np.where(size > limit, limit / np.where(size > 0, size, 1.0), 1.0)
    tau = trial * scale[..., None]
    return tau, slip - tau / law.k_0, reached


def plastic_slip_work(tau_a, tau_b, slip_p_a, slip_p_b):
    """Work (J/m^2, (n,)) of the plastic slip over a step from stress tau_a to tau_b (Pa,
    (n, d)) and plastic slip slip_p_a to slip_p_b (m, (n, d)): the mean stress on the plastic
    slip. The trapezoidal work of the step, (tau_a + tau_b) / 2 on the slip's increment, is
    this plus the change of the elastic energy |tau|^2 / (2 k_0), exactly."""
    return 0.5 * np.einsum("ni,ni->n", tau_a + tau_b, slip_p_b - slip_p_a)


def bar_force(eps, eps_p, E_s, area, f_y=np.inf):
    """Axial force (N, N/m in 2D) of elastic-perfectly plastic bars in tension and in
    compression, and the plastic strain a step ending there would accept: eps, eps_p the total
    and plastic strain (-), E_s (Pa), area (m^2, m^2/m in 2D), f_y (Pa, inf: elastic).
    Vectorised."""
    sigma = np.clip(E_s * (eps - eps_p), -f_y, f_y)
    return area * sigma, eps - sigma / E_s


class BondedBars:
    """The bars of a case with bond-slip: nodes of their own, the cables between them and
    the bond to the concrete (module docstring). The same interface as cables.Rebars where
    the integrator, the reports and the stable step use it.

    X (n, d) the nodes' points (m), m_s (n,) their masses (kg, kg/m in 2D), surface (n,) their
    bond surfaces p l (m^2, m^2/m in 2D); a, b (n_seg,) the segments' nodes, L (m) their
    lengths; bonded (n_b,) the nodes whose bond this rank computes, lam (n_b, d+1) their
    barycentric weights in their cells and comps (n_b, d+1, d) those cells' components;
    counted (bool, n_seg): segments whose first node's cell this rank owns (drawn and
    counted once over the ranks); cell_a their cells (local)."""

    STATE = ("u_s", "v_s", "slip_p", "slip_max", "tau", "eps_p", "ruptured", "plastic_work", "rupture_work", "bond_work",
             "peak_force", "force_max", "N", "_work", "_u_last", "_f_last", "_node_work", "_us_last", "_fs_last", "_us_n")

    def __init__(self, space, lines, areas, diameter, E_s, f_y, rho_s, size, comm, law, eps_u=None,
                 small_strain=False):
        self.space, self.comm, self.law, self.small_strain = space, comm, law, small_strain
        self.E_s, self.f_y = E_s, (np.inf if f_y is None else f_y)
        self.eps_u = np.inf if eps_u is None else eps_u
        node = self.node = nodes(space, lines, size, comm, samples=1, merge=False)
        n, d = len(node.bar), space.gdim
        self.d, self.X = d, node.x
        area = areas[node.bar]
        self.m_s = rho_s * area * node.length
        self.surface = 4 * area / diameter * node.length
        a = np.flatnonzero(node.bar[:-1] == node.bar[1:])
        b = a + 1
        self.a, self.b = a, b
        self.chord0 = node.x[b] - node.x[a]
        self.L = np.linalg.norm(self.chord0, axis=1)
        self.area = area[a]
        n_owned = space.n_owned_cells
        self.bonded = np.flatnonzero((node.cell >= 0) & (node.cell < n_owned))
        cells = node.cell[self.bonded]
        self.lam = barycentric(space.x[space.cell_dofs[cells]], node.x[self.bonded])
        self.comps = space.components(space.cell_dofs[cells][:, :, None]).reshape(len(cells), d + 1, d)
        self.cell_a = node.cell[a]
        self.counted = (self.cell_a >= 0) & (self.cell_a < n_owned)
        self._rank0 = comm.rank == 0
        self._on_rank0 = np.full(len(a), self._rank0)
        self.u_s, self.v_s, self._us_n = np.zeros((n, d)), np.zeros((n, d)), np.zeros((n, d))
        self.slip_p, self.tau, self.slip_max = np.zeros((n, d)), np.zeros((n, d)), np.zeros(n)  # m, Pa, m
        self.eps_p, self.ruptured = np.zeros(len(a)), np.zeros(len(a), dtype=bool)
        self.N = np.zeros(len(a))  # N (N/m in 2D): the cables' forces at the last step
        # J (J/m in 2D): cables' yield and ruptures (rank 0), plastic slip (this rank's nodes)
        self.plastic_work = self.rupture_work = self.bond_work = 0.0
        self.peak_force = self.force_max = 0.0
        own = space.n_owned_dofs * d
        self._own = slice(0, own)
        self._work, self._u_last, self._f_last = 0.0, np.zeros(own), np.zeros(own)
        self._bar = np.unique(self.comps.ravel())  # the concrete components the bond touches
        self._node_work, self._us_last, self._fs_last = 0.0, np.zeros(n * d), np.zeros(n * d)
        self._all = np.arange(n * d)

    @property
    def count(self):
        """Number of segments over all ranks. Collective."""
        return self.comm.allreduce(int(self.counted.sum()))

    @property
    def mass(self):
        """The bars' mass (kg, kg/m in 2D)."""
        return float(self.m_s.sum())

    @property
    def ruptures(self):
        """Number of ruptured segments. Collective (every rank knows them all)."""
        return self.comm.allreduce(int((self.ruptured & self.counted).sum()))

    @property
    def dissipated(self):
        """Energy (J, J/m in 2D) this rank's share of the bars dissipated: the cables' plastic
        work and ruptures (rank 0) and the bond's plastic slip (the nodes it computes)."""
        return self.plastic_work + self.rupture_work + self.bond_work

    @property
    def kinetic_energy(self):
        """Kinetic energy (J, J/m in 2D) of the nodes at the last mid-step, on rank 0."""
        return 0.5 * float(self.m_s @ np.einsum("ni,ni->n", self.v_s, self.v_s)) if self._rank0 else 0.0

    def add_mass(self, m):
        """Nothing: the nodes carry the bars' mass themselves."""

    def segments(self, u, scale=1.0):
        """The two ends (n_seg, 2, d) (m) of every segment at the nodes' displacement
        magnified ``scale`` times (u, the concrete's, is not needed: the nodes move on their
        own)."""
        x = self.X + scale * self.u_s
        return np.stack([x[self.a], x[self.b]], axis=1)

    def explicit_step(self, u, h):
        """The explicit step at the concrete displacement u (all local components, m): the
        forces (N) the bond puts on the concrete (owned components), returned; the bond and
        cable states accepted; the nodes advanced by central differences over h (s) and the
        step's work booked. Collective (one reduction)."""
        f, f_s = np.zeros_like(u), np.zeros_like(self.u_s)
        self._bond(u, f, f_s)
        if self.comm.size > 1:
            self.comm.Allreduce(MPI.IN_PLACE, f_s, op=MPI.SUM)
        self._cables(f_s)
        self._work += _book_work(self._bar, f, u, self._f_last, self._u_last)
        self._node_work += _book_work(self._all, f_s.ravel(), self.u_s.ravel(), self._fs_last, self._us_last)
        np.copyto(self._us_n, self.u_s)
        self.v_s += h * f_s / self.m_s[:, None]
        self.u_s += h * self.v_s
        return f

    def _bond(self, u, f, f_s):
        """The bond forces at u: on this rank's bonded nodes into f_s, their reactions on
        the concrete into f; the bond state accepted."""
        i = self.bonded
        s = self.u_s[i] - np.einsum("nj,nji->ni", self.lam, u[self.comps])
        tau, slip_p, self.slip_max[i] = bond_stress(self.law, s, self.slip_p[i], self.slip_max[i])
        # the step's mean stress: with the trapezoidal work booked, what is left stored is
        # then exactly the elastic |tau|^2 / (2 k_0)
        self.bond_work += float(self.surface[i] @ plastic_slip_work(self.tau[i], tau, self.slip_p[i], slip_p))
        self.slip_p[i], self.tau[i] = slip_p, tau
        F = -self.surface[i, None] * tau
        f_s[i] = F
        f += np.bincount(self.comps.ravel(), weights=(-self.lam[:, :, None] * F[:, None, :]).ravel(),
                         minlength=len(f))

    def _cables(self, f_s):
        """The cables' forces between nodes into f_s; their state accepted."""
        a, b = self.a, self.b
        eps, c, ell = chord_strain(self.chord0, self.u_s[b] - self.u_s[a], self.L, self.small_strain)
        N, eps_p = bar_force(eps, self.eps_p, self.E_s, self.area, self.f_y)
        N = np.where(self.ruptured, 0.0, N)
        pull = N[:, None] * c / ell[:, None]
        f_s[a] += pull  # a node is the first of one segment at most, and the second of one
        f_s[b] -= pull
        # the step's mean force on the plastic strain, as the bond's (plastic_slip_work): the
        # nodes go in and out of yield within a few steps, and the end force alone would
        # book more than the forces did (each entry into yield by half the force's rise)
        if self._rank0:
            self.plastic_work += float(np.sum(0.5 * self.L * (self.N + N) * (eps_p - self.eps_p)))
        self.N = N
        _, rupture, self.force_max = _accept(self.L, self.area, float(self.E_s), float(self.eps_u), self._on_rank0,
                                             eps, N, eps_p, self.eps_p, self.ruptured)
        self.rupture_work += rupture
        self.peak_force = max(self.peak_force, self.force_max)

    def stored_energy(self, u_a, u_b):
        """The bars' and bond's energy at the mid-step (J, J/m in 2D), this rank's share: the
        trapezoidal work of their forces on the concrete (owned components) and on the nodes
        (rank 0) up to the last step's start, plus half of that step's, less the dissipated
        energy (cables.Rebars.stored_energy). u_a, u_b: the concrete at the step's start and
        end."""
        own = self._own
        energy = self._work + 0.5 * self._f_last @ (u_b[own] - u_a[own]) - self.dissipated
        if self._rank0:
            energy += self._node_work + 0.5 * self._fs_last @ (self.u_s - self._us_n).ravel()
        return energy

    def spring_terms(self, to_global, n_concrete):
        """The explicit operator's springs and the nodes' masses, for the stable step
        (stable_step.coupled_omega2): global components (s, v, d) and factors (s, v) with
        K = sum_j S_j S_j^T on each axis, and the nodes' global components and masses (kg),
        numbered after the n_concrete components of the concrete. Each term once over the
        ranks: the cables and nodes on rank 0, the bonds on the rank computing them. A bond's
        tangent is at most k_0 p l in every direction (radial return: the elastic k_0 or less), a
        cable's E_s A / L."""
        d = self.d
        node_ids = n_concrete + np.arange(len(self.X) * d).reshape(-1, d)
        width = d + 2
        i = self.bonded
        bond_comps = np.concatenate([node_ids[i][:, None, :], to_global(self.comps).reshape(len(i), d + 1, d)], axis=1)
        bond_S = np.sqrt(self.law.k_0 * self.surface[i])[:, None] * np.column_stack([np.ones(len(i)), -self.lam])
        if not self._rank0:
            return bond_comps, bond_S, np.empty(0, np.int64), np.empty(0)
        seg_comps = np.repeat(node_ids[self.a][:, None, :], width, axis=1)
        seg_comps[:, 1] = node_ids[self.b]
        seg_S = np.zeros((len(self.a), width))
        seg_S[:, 0], seg_S[:, 1] = -1.0, 1.0
        seg_S *= np.sqrt(self.E_s * self.area / self.L)[:, None]
        return (np.concatenate([bond_comps, seg_comps]), np.concatenate([bond_S, seg_S]), node_ids.ravel(),
                np.repeat(self.m_s, d))
