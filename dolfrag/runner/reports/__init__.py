"""Per-kind reports of a run: each ``applies(case)``, observes the steps, adds its block to
summary.json (``summarise``) and draws its figures. A new kind of case adds a module here
and its class to REPORTS; the time loop does not change."""
from dolfrag.runner.reports.bar import BarReport
from dolfrag.runner.reports.bunker import BunkerReport
from dolfrag.runner.reports.debris import DebrisReport
from dolfrag.runner.reports.expanding import ExpandingBarReport
from dolfrag.runner.reports.wall import WallReport

REPORTS = (WallReport, BunkerReport, ExpandingBarReport, BarReport, DebrisReport)  # summary.json's order of blocks
