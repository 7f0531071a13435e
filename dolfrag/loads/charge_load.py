"""A charge's blast on a meshed boundary: every loaded facet gets its own p(t).

Each facet is read at its midpoint, as loads.unit_pressure_vector reads a region (the
degree-1 rule, exact for the P1 test functions on flat facets): its distance R to the
charge, Z = R / W^(1/3), its angle of incidence a (between the facet's outward normal
and the direction to the charge; a > 90 degrees: it faces away) give, by
loads.charge.blast_parameters, the arrival time t_a, the reflected peak P_r(a), the
positive phase duration t_o and the reflected impulse i_r(a); its pressure is the
Friedlander positive phase p(t) = P_r (1 - s) exp(-alpha s), s = (t - t_a) / t_o in [0, 1],
alpha reproducing i_r (loads.friedlander_alpha). The nodal forces are then

    f(t) = B p(t),   B[(dof, k), facet] = -n_k |facet| / d   for the d corner dofs,

B built once (N/Pa), so a step costs one vectorised Friedlander evaluation over the
facets and one sparse product. Every rank holds its owned cells' facets; their forces
fall on owned dof components only (a DG dof belongs to its cell), so no communication
is needed and the forces do not depend on the partition.
"""
import numpy as np
from scipy import sparse

from dolfrag.case import CaseError
from dolfrag.loads import charge, explosives, friedlander, friedlander_alpha
from dolfrag.space import facet_measures

# times of mean_pressure's table over the load: its linear interpolation between them is
# within 1.3e-3 of the peak on panel-charge's face (tests/test_charge.py)
TABLE = 20001
# the per-facet arrays gathered on every rank (the mean pressure, plots, summary)
FIELDS = ("x", "area", "R", "Z", "angle", "t_a", "P", "t_o", "i", "alpha")


def tnt_mass(load):
    """W (kg of TNT) of a charge case.Load."""
    return explosives.tnt_mass(load.mass, load.explosive, load.equivalence)


def facet_blast(load, x, normal):
    """{name: (n,) array} of FIELDS but x and area for facets with midpoints x (n, gdim) m
    and outward unit normals (n, gdim) under the charge case.Load ``load``: R (m), Z
    (m/kg^(1/3)), angle (rad), t_a (s), P (Pa, reflected at the angle), t_o (s), i (Pa s,
    reflected at the angle), alpha (-)."""
    to_charge = np.asarray(load.position) - x
    R = np.linalg.norm(to_charge, axis=1)
    angle = np.arccos(np.clip(np.einsum("ij,ij->i", to_charge, normal) / R, -1.0, 1.0))
    W = tnt_mass(load)
    blast = charge.blast_parameters(W, R, load.burst, angle)
    P, t_o, i = blast["P_r"], blast["t_o"], blast["i_r"]
    return {"R": R, "Z": R / np.cbrt(W), "angle": angle, "t_a": blast["t_a"], "P": P, "t_o": t_o, "i": i,
            "alpha": decay_coefficients(P, t_o, i)}


def decay_coefficients(P, t_o, i):
    """alpha (-) of the Friedlander positive phase of peak P (Pa), duration t_o (s) and
    impulse i (Pa s), per facet (arrays): loads.friedlander_alpha of i / (P t_o)."""
    return np.array([friedlander_alpha(k) for k in np.ravel(i / (P * t_o))]).reshape(np.shape(P))


def check_range(load, R, comm):
    """CaseError unless every loaded facet's scaled distance is in the burst's fitted
    range; R (n,) m this rank's distances. Collective."""
    W = tnt_mass(load)
    low, high = charge.scaled_range(load.burst)
    R_min = comm.allreduce(R.min(initial=np.inf), op=min)
    R_max = comm.allreduce(R.max(initial=0.0), op=max)
    Z_min, Z_max = R_min / np.cbrt(W), R_max / np.cbrt(W)
    if Z_min < low or Z_max > high:
        raise CaseError(f"load.position = {list(load.position)}: the loaded facets lie at R = {R_min:.4g} to "
                        f"{R_max:.4g} m, Z = R / W^(1/3) = {Z_min:.4g} to {Z_max:.4g} m/kg^(1/3) with W = "
                        f"{W:.4g} kg TNT (load.mass = {load.mass!r}); the {load.burst} fits cover Z in "
                        f"[{low:g}, {high:g}] m/kg^(1/3)")


def corner_dofs(space, cells, vertices):
    """(n, gdim) the dofs of each facet's corners in its cell (cells (n,), vertices (n, d))."""
    on_facet = (space.cell_vertices[cells][:, :, None] == vertices[:, None, :]).any(axis=2)
    return space.cell_dofs[cells][on_facet].reshape(len(cells), space.gdim)  # a simplex facet: gdim corners


def force_matrix(space, dofs, normal, area):
    """(rows, B): the owned flat components the facets load and B (len(rows), n) csr, N/Pa,
    the nodal forces of 1 Pa on each facet (module docstring)."""
    n, d = dofs.shape
    gdim = space.gdim
    comps = gdim * dofs[:, :, None] + np.arange(gdim)                    # (n, d, gdim)
    values = np.broadcast_to((-normal * (area / d)[:, None])[:, None, :], comps.shape)
    columns = np.broadcast_to(np.arange(n)[:, None, None], comps.shape)
    rows, local = np.unique(comps.ravel(), return_inverse=True)
    B = sparse.csr_matrix((values.ravel(), (local, columns.ravel())), shape=(len(rows), n))
    return rows.astype(np.int64), B


class ChargeLoad:
    """The charge case.Load ``load`` on boundary ``load.boundary`` of domain (mesh.py) and
    space (space.py). Collective; CaseError if a facet's Z is outside the fits.

    rows, forces(t): the nodal load of loads/nodal.py (owned components, N).
    pressures(t) (n,) Pa: this rank's facets' p(t).
    facets: {FIELDS name: array} of every loaded facet (all ranks', the same on each,
    sorted by midpoint), for mean_pressure, the figures and the summary.
    """

    def __init__(self, load, space, domain, comm):
        cells, vertices = space.boundary_facets(domain.facet_tags, domain.boundary_tag(load.boundary))
        normal = space.boundary_normals(domain.facet_tags, domain.boundary_tag(load.boundary))
        mine = cells < space.n_owned_cells  # an exterior facet is assembled by its cell's owner
        cells, vertices, normal = cells[mine], vertices[mine], normal[mine]
        corners = space.vertex_x[vertices]
        x, area = corners.mean(axis=1), facet_measures(corners)
        check_range(load, np.linalg.norm(np.asarray(load.position) - x, axis=1), comm)
        blast = facet_blast(load, x, normal)
        self.load, self.t_a = load, blast["t_a"]
        self._phase = friedlander(blast["P"], blast["t_o"], blast["alpha"])
        self.rows, self.B = force_matrix(space, corner_dofs(space, cells, vertices), normal, area)
        self.facets = _gathered({"x": x, "area": area, **blast}, comm)
        self._all_phase = friedlander(self.facets["P"], self.facets["t_o"], self.facets["alpha"])
        self._table = None  # mean_pressure's, made at its first call with an array

    def pressures(self, t):
        return self._phase(t - self.t_a)

    def forces(self, t):
        return self.B @ self.pressures(t)

    def mean_pressure(self, t):
        """The area-weighted mean p (Pa) over the loaded boundary at t (s, float or array):
        the total normal force over the area, what a uniform load of the same resultant
        would be (the history's load column, the wall report's estimates). Local. A float
        gets the exact mean; an array is read from a table of exact means (TABLE times over
        the load, and every facet's arrival and end), linear between them: the wall
        report's estimates ask for millions of times (4 million: 52 s exact, measured on
        panel-charge)."""
        if np.ndim(t) == 0:
            return self._mean_at(float(t))
        if self._table is None:
            f = self.facets
            times = np.unique(np.concatenate([np.linspace(0.0, self.end(), TABLE), f["t_a"], f["t_a"] + f["t_o"]]))
            self._table = times, np.array([self._mean_at(s) for s in times])
        return np.interp(t, *self._table, left=0.0, right=0.0)

    def _mean_at(self, t):
        area = self.facets["area"]
        return area @ self._all_phase(t - self.facets["t_a"]) / area.sum()

    def end(self):
        """The time (s) after which every facet's positive phase is over."""
        return float(np.max(self.facets["t_a"] + self.facets["t_o"]))

    def extremes(self):
        """(nearest, farthest): the indices in ``facets`` of the loaded facets closest to and
        farthest from the charge."""
        return int(np.argmin(self.facets["R"])), int(np.argmax(self.facets["R"]))

    def point_pressure(self, index):
        """p(t) (Pa, vectorised over t in s) at loaded facet ``index`` of ``facets``."""
        f = self.facets
        return lambda t: friedlander(f["P"][index], f["t_o"][index], f["alpha"][index])(np.asarray(t) - f["t_a"][index])

    def summary(self):
        """summary.json's "load" block: the charge, W, the Z range, and the blast at the
        nearest and farthest loaded facets (SI)."""
        f, load = self.facets, self.load
        points = {}
        for name, i in zip(("nearest", "farthest"), self.extremes()):
            points[name] = {"x_m": f["x"][i].tolist(), "R_m": f["R"][i], "Z_m_kg13": f["Z"][i],
                            "angle_deg": np.degrees(f["angle"][i]), "t_a_s": f["t_a"][i], "P_r_Pa": f["P"][i],
                            "t_o_s": f["t_o"][i], "i_r_Pa_s": f["i"][i], "alpha": f["alpha"][i]}
        return {"signal": "charge", "explosive": load.explosive, "mass_kg": load.mass,
                "equivalence": load.equivalence, "tnt_mass_kg": tnt_mass(load), "burst": load.burst,
                "position_m": list(load.position), "Z_min_m_kg13": float(f["Z"].min()),
                "Z_max_m_kg13": float(f["Z"].max()), "peak_Pa": float(f["P"].max()),
                "duration_s": self.end(), **points}


def _gathered(arrays, comm):
    """{name: array} of every rank's facets, concatenated and sorted by midpoint (x, then
    y, then z), so that every rank, and every rank count, holds them in one order."""
    parts = comm.allgather(arrays)
    joined = {name: np.concatenate([p[name] for p in parts]) for name in arrays}
    order = np.lexsort(joined["x"].T[::-1])
    return {name: value[order] for name, value in joined.items()}
