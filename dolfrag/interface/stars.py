"""Star-local exact solves of the implicit interface step.

With a lumped mass and nodal interface quadrature a link joins two copies of the same
mesh vertex, so the step matrix ``diag(m) + c K_i`` is block-diagonal over vertex stars
(all copies of one vertex: 2D 1-10 copies, 3D up to ~50). Stars are grouped by size, so
that each group is one dense array (the linear step's blocks are inverted once, batched),
and laid out flat (FlatStars) for the compiled loops over the stars that solve each step
(solver/elastic_kernel.py, solver/star_kernel.py). A rank solves the stars of the vertices
it owns, which it holds whole: no communication.
"""
from dataclasses import dataclass

import numpy as np


@dataclass
class StarGroup:
    """Stars with k copies.

    comps (n_s, k*gdim): flat dof components of each star.
    links (n_s, L): the star's links (indices into the link table), padded with 0 where
    ``valid`` (n_s, L) is False; slot_A, slot_B (n_s, L): the copies each link joins.
    """
    comps: np.ndarray
    links: np.ndarray = None
    valid: np.ndarray = None
    slot_A: np.ndarray = None
    slot_B: np.ndarray = None


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

    def flat(self, links):
        """The stars laid out flat (FlatStars), in the order of the groups and their rows."""
        return FlatStars(self, links)

    def _assemble(self, g, blocks, c):
        """The star blocks (n_s, k*gdim, k*gdim) of group g: c * sum over links of
        [[D, -D], [-D, D]], blocks (n_links, gdim, gdim) the link stiffnesses D (N/m)."""
        d, grp = self.gdim, self.groups[g]
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
        return A.reshape(n_s, q, q)

    def inverses(self, m, blocks, c):
        """Per group, in order, the inverses (n_s, q, q) of diag(m) + c * sum over links of
        [[D, -D], [-D, D]] (one group at a time: a 3D mesh's inverses are its largest array).

        m: flat lumped mass (kg) of every local dof component; blocks (n_links, gdim, gdim)
        link stiffnesses D (N/m); c (s^2) their factor in the step matrix. Rows and columns
        of prescribed components are zero (they get no increment): each inverse stays
        symmetric."""
        for g, grp in enumerate(self.groups):
            A = self._assemble(g, blocks, c)
            q = A.shape[1]
            A[:, np.arange(q), np.arange(q)] += m[grp.comps]
            fixed = self.constrained[grp.comps]
            A[fixed[:, :, None] | fixed[:, None, :]] = 0.0
            A[:, np.arange(q), np.arange(q)] += fixed
            inv = np.linalg.inv(A)
            inv[fixed[:, :, None] | fixed[:, None, :]] = 0.0  # prescribed: ignore rhs, give 0
            yield inv


class FlatStars:
    """A rank's stars flat, as compiled loops over the stars read them: star s owns the
    components comps[comp_off[s]:comp_off[s + 1]] (copy-major, gdim per copy) and the star
    links [link_off[s], link_off[s + 1]), each the link links[i] of the link table, joining
    the star's copies slot_A[i] and slot_B[i]."""

    def __init__(self, stars, links):
        comps, star_links, slot_A, slot_B, q, L = [], [], [], [], [], []
        for grp in stars.groups:
            n_s, k_d = grp.comps.shape
            comps.append(grp.comps)
            q.append(np.full(n_s, k_d))
            if grp.links is None or grp.links.shape[1] == 0:
                L.append(np.zeros(n_s, dtype=np.int64))
                continue
            valid = grp.valid  # valid slots come first in each row
            star_links.append(grp.links[valid])
            slot_A.append(grp.slot_A[valid])
            slot_B.append(grp.slot_B[valid])
            L.append(valid.sum(axis=1))
        q, L = np.concatenate(q), np.concatenate(L)
        cat = lambda a: np.concatenate(a) if a else np.zeros(0, dtype=np.int64)  # noqa: E731
        self.gdim, self.n_links = stars.gdim, len(links)
        self.comps = np.ascontiguousarray(np.concatenate([c.ravel() for c in comps]), dtype=np.int64)
        self.links = np.ascontiguousarray(cat(star_links), dtype=np.int64)
        self.slot_A = np.ascontiguousarray(cat(slot_A), dtype=np.int64)
        self.slot_B = np.ascontiguousarray(cat(slot_B), dtype=np.int64)
        self.comp_off = np.concatenate([[0], np.cumsum(q)]).astype(np.int64)
        self.link_off = np.concatenate([[0], np.cumsum(L)]).astype(np.int64)
        self.star_of_link = np.repeat(np.arange(len(L)), L)

    @property
    def n_stars(self):
        return len(self.comp_off) - 1
