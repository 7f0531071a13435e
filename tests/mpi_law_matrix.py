"""Under mpirun: each given built-in case with every law of the registry it accepts, as the
short runs of tests/test_law_matrix.py, one after the other in this one process.

argv: output directory, then case names. Each run writes into <out>/<case>/<law>/; rank 0
writes <out>/statuses.json, {case: {law: summary status}}.
"""
import json
import sys
from pathlib import Path

from mpi4py import MPI

import dolfrag
from dolfrag.case import load_case
from dolfrag.interface.models import LAWS
from test_law_matrix import REFUSED, keys

out, names = Path(sys.argv[1]), sys.argv[2:]
statuses = {}
for name in names:
    for law in LAWS:
        if (name, law) not in REFUSED:
            summary = dolfrag.run(load_case(name, keys(name, law)), out / name / law, quiet=True)
            statuses.setdefault(name, {})[law] = [summary["status"], summary["ranks"]]
if MPI.COMM_WORLD.rank == 0:
    (out / "statuses.json").write_text(json.dumps(statuses))
