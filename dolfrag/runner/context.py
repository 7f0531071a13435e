"""What the observers of a run share: the problem, the integrator, the step just taken, and
what the run asks of each observer."""
from typing import NamedTuple

from dolfrag.post.fragments import fragments


class Step(NamedTuple):
    """The step just taken: its number k (1..n_steps), its start time t_n (s), and the
    Energies at its mid-step when a history row is due, else None."""
    k: int
    t_n: float
    energies: object


class Observer:
    """What the run asks of an object that follows it, each part declared: ``columns``, its
    history.csv columns, which ``values(step)`` gives when a row is due; ``observe(step)``,
    called after every step; ``summarise(summary, final)``, its block of summary.json at
    the end (runner/final.py's result). A part left None (no columns) is not asked."""
    columns = ()
    values = observe = summarise = None


class RunContext:
    """problem: problem.Problem; integ: its solver.Integrator; comm; out: the output folder (Path);
    stretch: stretch.Stretch or None; break_time (n_links,) s: when each owned link broke
    (NaN while sound; kept by runner/breaks.py)."""

    def __init__(self, problem, integ, comm, out, stretch, break_time):
        self.problem, self.integ, self.comm, self.out = problem, integ, comm, out
        self.stretch, self.break_time = stretch, break_time
        self.case, self.space, self.links = problem.case, problem.space, problem.links

    def fragments(self, of_cells=False, displaced=True):
        """post.fragments.fragments of the current state, in the displaced configuration or
        (displaced=False) the reference one. Collective."""
        integ = self.integ
        return fragments(self.space, self.links, integ.model.broken(), integ.m, integ.v.x.array,
                         integ.u.x.array if displaced else None, self.break_time, of_cells)
