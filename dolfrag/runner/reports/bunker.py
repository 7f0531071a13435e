"""The bunker (geometry.kind = "bunker"): the long wall's centre deflection (a history column),
and the ``bunker`` block: its peak against thin plates of the panel, and the free fragments
of every wall and the roof (post/bunker.py)."""
import numpy as np

from dolfrag import bunker
from dolfrag.post import bunker as post
from dolfrag.post.figures import DAMAGE_RANGE, broken_mesh_png, deflection_png, figure_title
from dolfrag.post.wall import peak
from dolfrag.runner.context import Observer


class BunkerReport(Observer):
    columns = ["w_long_wall_m"]
    STATE = ("deflection",)  # s, m: the long wall's centre deflection, outward (+y)

    @staticmethod
    def applies(case):
        return case.geometry.kind == "bunker"

    def __init__(self, ctx):
        self.ctx = ctx
        space = ctx.space
        lay = bunker.layout(ctx.case.geometry)
        points = post.long_wall_centre(space.x[:space.n_owned_dofs], lay, ctx.case.mesh.size)
        self.centre = space.gdim * points + 1
        self.deflection = ([], [])

    def values(self, step):
        integ = self.ctx.integ
        total, count = self.ctx.comm.allreduce(np.array([integ.u.x.array[self.centre].sum(), len(self.centre)]))
        w = total / max(count, 1)
        self.deflection[0].append(integ.t)
        self.deflection[1].append(w)
        return [w]

    def summarise(self, summary, final):
        case = self.ctx.case
        w, i = peak(np.asarray(self.deflection[1]))
        plates = post.plate_estimates(case.geometry, case.material)
        summary["bunker"] = {"long_wall": {"peak_deflection_m": w, "peak_time_s": float(self.deflection[0][i]),
                                           "plate_per_pressure": plates},
                             "pieces": post.pieces(final.table)}

    def figures(self, folder, final):
        ctx = self.ctx
        self._opened(folder, final)
        t = np.asarray(self.deflection[0])
        pressure = ctx.problem.pressure(t)
        plates = final.summary["bunker"]["long_wall"]["plate_per_pressure"]
        deflection_png(t, self.deflection[1], (t, pressure * plates["clamped_m_Pa"]), folder / "deflection.png",
                       ctx.comm, f"long wall centre deflection ({ctx.case.name})", None,
                       "clamped thin plate, p(t) applied statically")

    def _opened(self, folder, final):
        """bunker.png: the bunker without its roof and door wall, seen from above the door,
        coloured by damage: the inside faces, where the explosion pushes, show their cracks."""
        ctx, integ = self.ctx, self.ctx.integ
        space, lay = ctx.space, bunker.layout(ctx.case.geometry)
        centroid = space.x[space.cell_dofs[:space.n_owned_cells]].mean(axis=1)
        kept = (centroid[:, 2] < lay.room[1][2]) & (centroid[:, 1] > lay.room[0][1])
        broken_mesh_png(space, integ.u, final.damage.x.array, folder / "bunker.png", "damage 1 - beta (-)",
                        figure_title(ctx.case.name, integ.t), cells=kept, view=(0.5, -1.0, 1.2),
                        rebars=ctx.problem.rebars, clim=DAMAGE_RANGE, note="roof and door wall left out")
