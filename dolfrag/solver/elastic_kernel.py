"""The linear (elastic springs) imex step, compiled: one loop over a rank's stars.

With linear springs K_i the implicit part of a step is, star by star,

    (M + h^2/4 K_i) dv = h (f - K_i u_n),

whose matrices A = M + h^2/4 K_i are inverted once (interface/stars.Stars.inverses). Per
star the loop gathers the star's f and u_n once and subtracts each of its links' spring
force K_l (u_B - u_A) (K_l the link's stiffness block in global components); then it
multiplies each star's result by its stored A^-1, one pass over the inverses.
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
def elastic_stars(comps, comp_off, link_off, slot_A, slot_B, K, inverse, inv_off, f, u, h, out, rhs, y):
    """out[comps] = h A^-1 (f - K_i u) per star.

    comps, comp_off, link_off, slot_A, slot_B: the flat star layout
    (interface/stars.FlatStars); K (L_total, d, d) N/m: each star link's stiffness block
    w (C_N n n^T + C_T T^T T) in global components; inverse: each star's A^-1 (q, q)
    row-major from inv_off[s] (symmetric; rows and columns of prescribed components
    zero); f (N), u (m): flat over local components, current on the stars' components;
    h (s); rhs, y: workspaces like comps.

    In three passes: every star's right-hand side, then every product with A^-1, then the
    scatter. The products then stream the inverses alone, without the gathers' cache misses
    between them (measured on 9,555 tetrahedra: 424-493 against 463-545 ns per
    element-step for the star step, one pass per star)."""
    n_stars = len(comp_off) - 1
    for s in range(n_stars):
        _right_hand_side(comps, comp_off[s], comp_off[s + 1], link_off[s], link_off[s + 1], slot_A, slot_B, K, f, u,
                         rhs, y)  # y holds u until the products overwrite it
    for s in range(n_stars):
        p0, q = comp_off[s], comp_off[s + 1] - comp_off[s]
        _product(inverse[inv_off[s]:inv_off[s] + q * q], rhs[p0:p0 + q], y[p0:p0 + q])
    for i in range(len(comps)):
        out[comps[i]] = h * y[i]


@njit(cache=True, error_model="numpy")
def _right_hand_side(comps, p0, p1, l0, l1, slot_A, slot_B, K, f, u, rhs, u_s):
    """rhs[p0:p1] = f - K_i u on one star's components comps[p0:p1], from its links
    [l0, l1); u_s[p0:p1] holds the star's u."""
    d = K.shape[1]
    # one gather of each component: a star's components lie in many cells, so each read
    # is a cache miss, and per link they would be read again (measured on 9,555
    # tetrahedra, 31 links a star: 575 against 350 ns per element-step for the springs)
    for i in range(p0, p1):
        rhs[i] = f[comps[i]]
        u_s[i] = u[comps[i]]
    for l in range(l0, l1):
        a, b = p0 + slot_A[l] * d, p0 + slot_B[l] * d
        for i in range(d):
            F = 0.0
            for j in range(d):
                F += K[l, i, j] * (u_s[b + j] - u_s[a + j])
            rhs[b + i] -= F
            rhs[a + i] += F


@njit(cache=True, error_model="numpy")
def _product(A_inv, r, y):
    """y = A^-1 r, A^-1 (q, q) symmetric, flat row-major."""
    q = len(r)
    if q < SHORT:  # y_i = (row i).r, four rows side by side (four independent chains)
        i = 0
        while i + 4 <= q:
            a0, a1, a2, a3 = 0.0, 0.0, 0.0, 0.0
            for j in range(q):
                r_j = r[j]
                a0 += A_inv[i * q + j] * r_j
                a1 += A_inv[(i + 1) * q + j] * r_j
                a2 += A_inv[(i + 2) * q + j] * r_j
                a3 += A_inv[(i + 3) * q + j] * r_j
            y[i], y[i + 1], y[i + 2], y[i + 3] = a0, a1, a2, a3
            i += 4
        for i in range(i, q):
            acc = 0.0
            for j in range(q):
                acc += A_inv[i * q + j] * r[j]
            y[i] = acc
    else:  # y = sum_j r_j (row j), no chains of dependent additions
        y[:] = 0.0
        for j in range(q):
            r_j = r[j]
            for i in range(q):
                y[i] += r_j * A_inv[j * q + i]


def warm():
    """Compile the kernel (2D and 3D) into numba's cache on a tiny star of each."""
    for d in (2, 3):
        q = 2 * d
        elastic_stars(np.arange(q), np.array([0, q]), np.array([0, 1]), np.array([0]), np.array([1]),
                      np.eye(d)[None].copy(), np.eye(q).ravel(), np.array([0, q * q]), np.ones(q), np.zeros(q), 1.0,
                      np.zeros(q), np.empty(q), np.empty(q))
