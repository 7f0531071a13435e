"""A bar loaded on one end (Hopkinson bar, spall): breaks from the free end, and the
``shpb`` block at post.shpb.MEASURE_TIME (or the end of a shorter run)."""
from dolfrag import loads
from dolfrag.reference import analytic, homogenise
from dolfrag.post import shpb
from dolfrag.post.fragments import breaks_by_time
from dolfrag.runner.fragment_times import FragmentTimes


def free_end(case):
    """x (m) of the far end of a rectangle bar loaded on its left or right edge, else None."""
    if case.geometry.kind != "rectangle" or case.load.boundary not in ("left", "right"):
        return None
    return case.geometry.length if case.load.boundary == "left" else 0.0


def free_end_probe(case, space, domain):
    """shpb.FreeEndProbe of the face opposite the loaded one of a bar (``free_end``)."""
    face = "right" if case.load.boundary == "left" else "left"
    dofs = space.boundary_dofs(domain.facet_tags, domain.boundary_tag(face))
    return shpb.FreeEndProbe(space.gdim * dofs[dofs < space.n_owned_dofs], 1.0 if face == "right" else -1.0)


class BarReport(FragmentTimes):
    """Measures the fragments at MEASURE_TIME when the run reaches it, and the free end's
    velocity every step (its pullback)."""
    STATE = (*FragmentTimes.STATE, "probe")

    @staticmethod
    def applies(case):  # a charge's spherical wave is not the bar's plane one
        return free_end(case) is not None and case.load.signal != "charge"

    def __init__(self, ctx):
        super().__init__(ctx, {shpb.MEASURE_TIME} if ctx.case.time.end >= shpb.MEASURE_TIME else set())
        self.free_end = free_end(ctx.case)
        self.probe = free_end_probe(ctx.case, ctx.space, ctx.problem.domain)

    def observe(self, step):
        super().observe(step)
        self.probe.record(self.ctx.integ.energy_time, self.ctx.integ.v.x.array)

    def summarise(self, summary, final):
        case, integ = self.ctx.case, self.ctx.integ
        summary["breaks"] = breaks_by_time(final.fragments, self.free_end)
        measured_at, at_measure = self.measured.get(shpb.MEASURE_TIME, (integ.t, final.fragments))
        sigma_c = self.ctx.problem.law.tensile_strength(case.interface, integ.model.C_N)
        rho, E = case.material.rho, case.material.E
        closed = None if sigma_c is None else analytic.bar_spall(
            loads.signal(self.ctx.problem.applied_load), analytic.wave_speed(E, rho), rho, sigma_c,
            case.geometry.length, loads.signal_end(self.ctx.problem.applied_load), at=measured_at)
        summary["shpb"] = shpb.shpb_block(final.fragments, at_measure, measured_at, self.free_end, sigma_c, rho, E,
                                          case.name, closed_form=closed,
                                          free_end_velocity=self.probe.series(self.ctx.comm),
                                          E_eff=homogenise.bar_modulus(case))

    def figures(self, folder, final):
        pass  # the common figures show it
