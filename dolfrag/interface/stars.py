"""Star-local exact solves of the implicit interface step.

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
    """Stars with k copies.

    comps (n_s, k*gdim): flat dof components of each star.
    links (n_s, L): the star's links (indices into the link table), padded with 0 where
    ``valid`` (n_s, L) is False; slot_A, slot_B (n_s, L): the copies each link joins.
    inv: the inverses of the linear step blocks (see Stars.factorise).
    """
    comps: np.ndarray
    links: np.ndarray = None
    valid: np.ndarray = None
    slot_A: np.ndarray = None
    slot_B: np.ndarray = None
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
        self.comm = space.mesh.comm
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
        self.constrained = np.zeros(n_dofs * d, dtype=bool)  # flat, per local component
        self.constrained[np.asarray(constrained, dtype=np.int64)] = True
        for g, grp in enumerate(self.groups):
            self._tabulate_links(grp, np.flatnonzero(self._link_group == g))

    def _tabulate_links(self, grp, mine):
        """Fill grp.links/valid/slot_A/slot_B: the links of each star, padded to the most."""
        rows = self._link_row[mine]
        order = np.argsort(rows, kind="stable")
        mine, rows = mine[order], rows[order]
        n_s = len(grp.comps)
        count = np.bincount(rows, minlength=n_s)
        column = np.arange(len(rows)) - np.repeat(np.cumsum(count) - count, count)
        shape = (n_s, count.max(initial=0))
        grp.links = np.zeros(shape, dtype=np.int64)
        grp.valid = np.zeros(shape, dtype=bool)
        grp.slot_A = np.zeros(shape, dtype=np.int64)
        grp.slot_B = np.zeros(shape, dtype=np.int64)
        grp.links[rows, column] = mine
        grp.valid[rows, column] = True
        grp.slot_A[rows, column] = self._slot_A[mine]
        grp.slot_B[rows, column] = self._slot_B[mine]

    def fixed(self, grp):
        """(n_s, k*gdim) bool: the group's prescribed components."""
        return self.constrained[grp.comps]

    def assemble(self, blocks, c=1.0):
        """Per group, the star blocks (n_s, k*gdim, k*gdim) of c * sum over links of
        [[D, -D], [-D, D]]: blocks (n_links, gdim, gdim) link stiffnesses D (N/m)."""
        d = self.gdim
        out = []
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
            out.append(A.reshape(n_s, q, q))
        return out

    def factorise(self, m, blocks, c):
        """Invert diag(m) + c * sum over links of [[D, -D], [-D, D]] for every star.

        m: flat lumped mass (kg) of every local dof component; blocks (n_links, gdim, gdim)
        link stiffnesses D (N/m); c (s^2) their factor in the step matrix.
        """
        for grp, A in zip(self.groups, self.assemble(blocks, c)):
            q = A.shape[1]
            A[:, np.arange(q), np.arange(q)] += m[grp.comps]
            fixed = self.constrained[grp.comps]
            A[fixed[:, :, None] | fixed[:, None, :]] = 0.0
            A[:, np.arange(q), np.arange(q)] += fixed
            inv = np.linalg.inv(A)
            inv[np.broadcast_to(fixed[:, None, :], inv.shape)] = 0.0  # prescribed: ignore rhs, give 0
            grp.inv = inv
