"""Fragments at given times (the step nearest each): output.fragments_at for summary.json,
or a report's own measuring time."""
from dolfrag.runner.context import Observer


class FragmentTimes(Observer):
    """``times`` (s); ``measured``: {time: (time of the step nearest it (s), Fragments)}."""
    STATE = ("pending", "measured")

    def __init__(self, ctx, times):
        self.ctx = ctx
        self.pending = sorted(set(times))
        self.measured = {}

    def observe(self, step):
        integ = self.ctx.integ
        while self.pending and integ.t >= self.pending[0] - integ.h / 2:  # the step nearest to it
            self.measured[self.pending.pop(0)] = (integ.t, self.ctx.fragments())


class RequestedFragments(FragmentTimes):
    """output.fragments_at: the summary's ``fragments_at`` list."""

    def __init__(self, ctx):
        super().__init__(ctx, ctx.case.output.fragments_at)

    def summarise(self, summary, final):
        if self.measured:
            summary["fragments_at"] = [{"requested_time_s": at, "time_s": t, **frags.to_dict()}
                                       for at, (t, frags) in sorted(self.measured.items())]
