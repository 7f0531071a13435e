"""Jump operator: displacement jumps of the links and the forces of link tractions."""
import numpy as np
import scipy.sparse as sp


class Jump:
    """g = B u for the links of this rank, and its transpose for forces.

    B has one row per link component (n_links * gdim, global x, y[, z] components)
    and one column per local dof component; built once.
    """

    def __init__(self, space, links):
        d = space.gdim
        n = len(links)
        rows = np.arange(n * d)
        cols_B = space.components(links.dof_B[:, None]).ravel()
        cols_A = space.components(links.dof_A[:, None]).ravel()
        n_cols = (space.V.dofmap.index_map.size_local + space.V.dofmap.index_map.num_ghosts) * d
        self.B = sp.csr_matrix((np.r_[np.ones(n * d), -np.ones(n * d)],
                                (np.r_[rows, rows], np.r_[cols_B, cols_A])), shape=(n * d, n_cols))
        self.BT = self.B.T.tocsr()
        self.links = links
        self.gdim = d

    def __call__(self, u):
        """Jumps (n_links, gdim) in global components, m."""
        return (self.B @ u).reshape(-1, self.gdim)

    def local(self, g):
        """Normal and tangential parts: g_N (n,), g_T (n, gdim-1)."""
        return (np.einsum("ij,ij->i", g, self.links.normal),
                np.einsum("ikj,ij->ik", self.links.tangents, g))

    def force(self, r_N, r_T):
        """Internal force vector B^T (weight t) of link tractions r_N (n,), r_T (n, gdim-1) in Pa,
        flat over local dof components (N, or N/m in 2D). It is the gradient of the stored
        energy: the interface pushes the dofs with its opposite."""
        t = r_N[:, None] * self.links.normal + np.einsum("ik,ikj->ij", r_T, self.links.tangents)
        return self.BT @ (self.links.weight[:, None] * t).ravel()

    def tangent_blocks(self, k_N, k_T):
        """(n, gdim, gdim) link stiffness w (k_N n n^T + k_T T^T T) in global components, N/m."""
        L = self.links
        k_N = np.broadcast_to(k_N, (len(L),))
        k_T = np.broadcast_to(k_T, (len(L),))
        nn = np.einsum("i,ij,ik->ijk", k_N, L.normal, L.normal)
        tt = np.einsum("i,ilj,ilk->ijk", k_T, L.tangents, L.tangents)
        return L.weight[:, None, None] * (nn + tt)
