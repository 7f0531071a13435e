"""The explicit stable step of the bulk with its bars (time.bars_step).

Central differences are stable for h < 2 / omega_max, omega_max^2 the largest eigenvalue of
M^-1 K over the explicit forces: the bulk's elasticity K_bulk (block-diagonal on the DG-P1
space, one block per cell) and the bars' tangent sum_j C_j^T G_j C_j (cables.py). In every
state G_j <= k_j I with k_j = (E_s A / L)_j (the material part is E_s A / L or 0 along the
chord, the geometric N / |c| < E_s A / L across it), so

    K_bars <= K_bar = sum_j k_j C_j^T C_j,   omega_max^2 <= lambda_max(M^-1 (K_bulk + K_bar))

for the whole run. Two ways to use it:

* ``"coupled"``: that eigenvalue itself. A cell no bar crosses is alone (K_bulk has no
  coupling between cells; the interfaces are implicit), so its eigenvalue is its own
  12 x 12 (6 x 6 in 2D) problem's. The cells the bars cross are coupled by them: that sparse
  problem is gathered on rank 0 by global component numbers, so its answer does not depend on
  the partition, and solved by Lanczos (scipy's eigsh) from a constant start vector.
  With bond-slip (rebar/bond.py) the bars' nodes are unknowns of their own, with their mass:
  the operator gains their components, the cables between them (k_j = E_s A / L) and the
  bond springs to their cells (k_0 p l, the bond's largest tangent), in the same problem.
* ``"weyl"``: omega_bulk^2 + a Gershgorin bound of M^-1 K_bar (Rebars.stiffness_bound):
  Weyl's inequality for a sum. Cheaper to form, and 1.06-1.48 times shorter than "coupled"
  on the built-in reinforced cases, where the bound adds the stiffest bar segment's
  eigenvalue to the stiffest cell's although the two lie apart.

Units: s, kg, N/m.
"""
import math

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from scipy.sparse.linalg import eigsh

from dolfrag import bulk, compat

# Below this many coupled components the eigenvalue is taken from the dense matrix
# (ARPACK needs more unknowns than Lanczos vectors, and a dense solve is then cheaper).
DENSE = 1500
# Lanczos' relative accuracy on the eigenvalue (0: ARPACK's machine precision), so that every
# rank count, whose numbering orders the same matrix differently, gets the same step.
LANCZOS_TOL = 0


def stable_step(rule, bulk_ops, bars, space):
    """dt (s): 2 / omega_max of the bulk with its bars (their mass in bulk_ops.m) by
    ``rule``, "coupled" or "weyl" (module docstring). Collective."""
    if rule == "weyl":
        omega2_bars = bars.stiffness_bound(bulk_ops.m.x.array, space.V.dofmap.index_map)
        return 2 / math.sqrt((2 / bulk_ops.dt_bulk)**2 + omega2_bars)
    return 2 / math.sqrt(coupled_omega2(bulk_ops, bars, space))


def coupled_omega2(bulk_ops, bars, space):
    """lambda_max(M^-1 (K_bulk + K_bar)) (1/s^2): the largest of the uncrossed cells' own
    eigenvalues and of the crossed cells' problem with the bars. Collective."""
    Ke = bulk_ops.K_cells.data
    n_cells, q = Ke.shape[:2]
    me = bulk_ops.m.x.array[:n_cells * q].reshape(n_cells, q)  # DG: cell by cell (bulk.assemble)
    comps = bars.comps[bars.comps < n_cells * q]
    crossed = np.zeros(n_cells, dtype=bool)
    crossed[comps // q] = True
    alone = (2 / bulk.cell_steps(Ke[~crossed], me[~crossed]))**2
    comm = space.mesh.comm
    omega2_alone = comm.allreduce(float(alone.max(initial=0.0)), op=MPI.MAX)
    index_map, d = space.V.dofmap.index_map, space.gdim
    to_global = lambda c: compat.global_indices(index_map, c.ravel() // d) * d + c.ravel() % d  # noqa: E731
    cells = np.arange(n_cells)[crossed]
    cell_comps = to_global(cells[:, None] * q + np.arange(q)).reshape(len(cells), q)
    springs = bars.spring_terms(to_global, index_map.size_global * d)
    parts = comm.gather((cell_comps, Ke[crossed], me[crossed], *springs), root=0)
    omega2 = None
    if comm.rank == 0:
        omega2 = max(omega2_alone, _largest(*(np.concatenate(p) for p in zip(*parts))))
    return comm.bcast(omega2, root=0)


def _largest(cell_comps, Ke, me, spring_comps, S, node_ids, node_m):
    """lambda_max(M^-1 (K_bulk + K_bar)) of the crossed cells (global component numbers
    cell_comps (n, q), blocks Ke (n, q, q) N/m, masses me (n, q) kg), the bars' springs
    (spring_comps (s, v, d) global components, S (s, v) factors: K_bar = sum_j S_j S_j^T on
    each axis; for perfect bond sqrt(k_j) times the barycentric weights of a segment's cell
    vertices) and the bars' own nodes when they have them (node_ids, masses node_m kg:
    rebar/bond.py)."""
    if len(cell_comps) == 0:
        return 0.0
    ids = np.concatenate([np.unique(cell_comps), np.sort(node_ids)])
    index = np.searchsorted(ids, cell_comps)
    n, q = len(ids), cell_comps.shape[1]
    K = sp.csr_matrix((Ke.ravel(), (np.repeat(index, q, axis=1).ravel(), np.tile(index, (1, q)).ravel())),
                      shape=(n, n))
    s, v, d = spring_comps.shape
    cols = np.searchsorted(ids, spring_comps)
    if np.any(ids[np.minimum(cols, n - 1)] != spring_comps):
        raise RuntimeError("a bar ties a component of no crossed cell")
    rows = np.broadcast_to(np.arange(s)[:, None, None] * d + np.arange(d), (s, v, d))
    C = sp.csr_matrix((np.broadcast_to(S[:, :, None], (s, v, d)).ravel(), (rows.ravel(), cols.ravel())),
                      shape=(s * d, n))
    m = np.zeros(n)
    m[index.ravel()] = me.ravel()
    m[np.searchsorted(ids, node_ids)] = node_m
    scale = sp.diags(1 / np.sqrt(m))
    A = scale @ (K + C.T @ C) @ scale
    if n <= DENSE:
        return float(np.linalg.eigvalsh(A.toarray())[-1])
    return float(eigsh(A, k=1, which="LA", v0=np.ones(n), tol=LANCZOS_TOL, return_eigenvectors=False)[0])
