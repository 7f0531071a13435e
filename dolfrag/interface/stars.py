"""Star-local exact solves of the implicit interface step (shared/DESIGN.md §4).

With a lumped mass and nodal interface quadrature a link joins two copies of the same
mesh vertex, so the step matrix ``diag(m) + c K_i`` is block-diagonal over vertex stars
(all copies of one vertex: 2D 1-10 copies, 3D up to ~50). Each star's block is
factorised once (here: inverted, they are small) and solved batched with numpy; stars
are grouped by size so each group is one dense array. A rank solves the stars of the
vertices it owns, which it holds whole: no communication.
"""
from dataclasses import dataclass

import numpy as np


@dataclass
class StarGroup:
    """Stars with k copies: comps (n_s, k*gdim) flat dof components, inv the inverse blocks."""
    comps: np.ndarray
    inv: np.ndarray = None


class Stars:
    """The stars of this rank's owned vertices.

    constrained: flat dof components whose velocity is prescribed to stay zero
    (supports); their rows and columns are replaced by the identity.
    """

    def __init__(self, space, links, constrained=()):
        d = space.gdim
        dofs = np.flatnonzero(space.dof_vertex < space.n_owned_vertices)
        order = np.argsort(space.dof_vertex[dofs], kind="stable")
        dofs = dofs[order]
        _, start, size = np.unique(space.dof_vertex[dofs], return_index=True, return_counts=True)
        self.gdim = d
        self.groups = []
        self.comps = space.components(dofs)
        n_dofs = len(space.dof_vertex)
        group_of = np.full(n_dofs, -1)
        row_of = np.full(n_dofs, -1)
        slot_of = np.full(n_dofs, -1)
        for g, k in enumerate(np.unique(size)):
            first = start[size == k]
            star_dofs = dofs[first[:, None] + np.arange(k)]
            self.groups.append(StarGroup(space.components(star_dofs)))
            group_of[star_dofs] = g
            row_of[star_dofs] = np.arange(len(first))[:, None]
            slot_of[star_dofs] = np.arange(k)
        self._link_group = group_of[links.dof_A]
        self._link_row = row_of[links.dof_A]
        self._slot_A = slot_of[links.dof_A]
        self._slot_B = slot_of[links.dof_B]
        assert np.array_equal(self._link_row, row_of[links.dof_B]), "a link leaves its star"
        self._fixed = np.zeros(n_dofs * d, dtype=bool)
        self._fixed[np.asarray(constrained, dtype=np.int64)] = True

    def factorise(self, m, blocks, c):
        """Invert diag(m) + c * sum over links of [[D, -D], [-D, D]] for every star.

        m: flat lumped mass (kg) of every local dof component; blocks (n_links, gdim, gdim)
        link stiffnesses D (N/m); c (s^2) their factor in the step matrix.
        """
        d = self.gdim
        for g, grp in enumerate(self.groups):
            n_s, q = grp.comps.shape
            k = q // d
            A = np.zeros((n_s, k, d, k, d))
            mine = self._link_group == g
            r, a, b = self._link_row[mine], self._slot_A[mine], self._slot_B[mine]
            D = c * blocks[mine]
            np.add.at(A, (r, a, slice(None), a), D)
            np.add.at(A, (r, b, slice(None), b), D)
            np.add.at(A, (r, a, slice(None), b), -D)
            np.add.at(A, (r, b, slice(None), a), -D)
            A = A.reshape(n_s, q, q)
            A[:, np.arange(q), np.arange(q)] += m[grp.comps]
            fixed = self._fixed[grp.comps]
            A[fixed[:, :, None] | fixed[:, None, :]] = 0.0
            A[:, np.arange(q), np.arange(q)] += fixed
            inv = np.linalg.inv(A)
            inv[np.broadcast_to(fixed[:, None, :], inv.shape)] = 0.0  # prescribed: ignore rhs, give 0
            grp.inv = inv

    def solve(self, rhs, out):
        """out[star comps] = star blocks^-1 rhs[star comps], for every owned star."""
        for grp in self.groups:
            out[grp.comps] = np.matmul(grp.inv, rhs[grp.comps][:, :, None])[:, :, 0]
