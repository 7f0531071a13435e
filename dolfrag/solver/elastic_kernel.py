"""The linear (elastic springs) imex step, compiled: one loop over a rank's stars.

With linear springs K_i the implicit part of a step is, star by star,

    (M + h^2/4 K_i) dv = h (f - K_i u_n),

whose matrices A = M + h^2/4 K_i are inverted once (interface/stars.Stars.inverses). Per
star the loop gathers the star's f and u_n once, subtracts each of its links' spring
force K_l (u_B - u_A) (K_l the link's stiffness block in global components), and
multiplies by the stored A^-1: one pass over the inverses, no interface-wide temporaries.
"""
import numpy as np
from numba import njit

# A star's product y = A^-1 rhs: with q >= SHORT components (3D stars, q ~ 50) as a sum of
# the rows of the symmetric A^-1, each an update along a contiguous row; below (2D stars,
# q ~ 12), as one dot product per row, rows too short for the first to pay. Measured on
# sound-bar (one process, CPU time per element-step of the whole star step): 3D, 9,555
# tetrahedra, 560 (rows summed) against 918 (dot products); 2D, 10,050 triangles, 114
# (dot products) against 132 (rows summed).
SHORT = 16


@njit(cache=True, error_model="numpy")
def elastic_stars(comps, comp_off, link_off, slot_A, slot_B, K, inverse, inv_off, f, u, h, out):
    """out[comps] = h A^-1 (f - K_i u) per star.

    comps, comp_off, link_off, slot_A, slot_B: the flat star layout
    (interface/stars.FlatStars); K (L_total, d, d) N/m: each star link's stiffness block
    w (C_N n n^T + C_T T^T T) in global components; inverse: each star's A^-1 (q, q)
    row-major from inv_off[s] (symmetric; rows and columns of prescribed components
    zero); f (N), u (m): flat over local components, current on the stars' components;
    h (s)."""
    d = K.shape[1]
    q_max = 0
    for s in range(len(comp_off) - 1):
        q_max = max(q_max, comp_off[s + 1] - comp_off[s])
    rhs, u_s, y = np.empty(q_max), np.empty(q_max), np.empty(q_max)
    for s in range(len(comp_off) - 1):
        p0, q = comp_off[s], comp_off[s + 1] - comp_off[s]
        # one gather of each component: a star's components lie in many cells, so each
        # read is a cache miss, and per link they would be read again (measured on 9,555
        # tetrahedra, 31 links a star: 575 against 350 ns per element-step for the springs)
        for i in range(q):
            rhs[i] = f[comps[p0 + i]]
            u_s[i] = u[comps[p0 + i]]
        for l in range(link_off[s], link_off[s + 1]):
            a, b = slot_A[l] * d, slot_B[l] * d
            for i in range(d):
                F = 0.0
                for j in range(d):
                    F += K[l, i, j] * (u_s[b + j] - u_s[a + j])
                rhs[b + i] -= F
                rhs[a + i] += F
        A_inv = inverse[inv_off[s]:inv_off[s] + q * q]
        if q < SHORT:  # y_i = (row i).rhs
            for i in range(q):
                acc = 0.0
                for j in range(q):
                    acc += A_inv[i * q + j] * rhs[j]
                y[i] = acc
        else:  # A^-1 is symmetric: y = sum_j rhs_j (row j), no chains of dependent additions
            y[:q] = 0.0
            for j in range(q):
                r_j = rhs[j]
                for i in range(q):
                    y[i] += r_j * A_inv[j * q + i]
        for i in range(q):
            out[comps[p0 + i]] = h * y[i]


def warm():
    """Compile the kernel (2D and 3D) into numba's cache on a tiny star of each."""
    for d in (2, 3):
        q = 2 * d
        elastic_stars(np.arange(q), np.array([0, q]), np.array([0, 1]), np.array([0]), np.array([1]),
                      np.eye(d)[None].copy(), np.eye(q).ravel(), np.array([0, q * q]), np.ones(q), np.zeros(q), 1.0,
                      np.zeros(q))
