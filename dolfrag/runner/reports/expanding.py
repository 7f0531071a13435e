"""The expanding bar (load.kind = "stretch"): the ``expanding_bar`` block, fragments in the
reference configuration against the closed forms at the stretch's rate."""
from dolfrag.post import expanding
from dolfrag.runner.context import Observer


class ExpandingBarReport(Observer):

    @staticmethod
    def applies(case):
        return case.load.kind == "stretch"

    def __init__(self, ctx):
        self.ctx = ctx

    def summarise(self, summary, final):
        ctx = self.ctx
        reference = ctx.fragments(displaced=False)
        summary["expanding_bar"] = expanding.block(reference, ctx.stretch.length, ctx.stretch.rate,
                                                   ctx.case.material, ctx.case.interface)

    def figures(self, folder, final):
        pass  # the common figures show it
