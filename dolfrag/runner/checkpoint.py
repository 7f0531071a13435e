"""Checkpoints: each rank's state of a run in <out>/checkpoint/, written atomically (a
temporary file, then a rename), so that a run stopped at any moment resumes from the last
complete one on the same number of ranks.

What a stateful object keeps is named by its ``STATE`` attribute (attribute names); an
object without one (a step solver) gives every array, number and list of objects among its
attributes. Arrays are restored in place, so that views other objects hold stay valid; a
property with a setter is restored through it (a part of an array, say).
"""
import copy
import dataclasses
import os
import pickle
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from dolfrag.case import CaseError

FOLDER = "checkpoint"
CASE = "case.pkl"
_NUMBERS = (np.ndarray, float, int, bool, np.number)


def _value(value):
    if hasattr(value, "x") and hasattr(value.x, "array"):  # a dolfinx Function
        return value.x.array.copy()
    if isinstance(value, np.ndarray):  # a read-only array of its own is a copy already (a property's)
        return value if value.flags.owndata and not value.flags.writeable else value.copy()
    if isinstance(value, list) and value and all(hasattr(item, "__dict__") for item in value):
        return [object_state(item) for item in value]
    return copy.deepcopy(value)


def _is_state(value):
    return isinstance(value, _NUMBERS) or (isinstance(value, list) and bool(value)
                                           and all(hasattr(item, "__dict__") for item in value))


def _names(obj, names=None):
    """The attributes of ``obj`` a state keeps: ``names``, else its STATE, else every array,
    number and list of objects among them (module docstring)."""
    names = getattr(obj, "STATE", None) if names is None else names
    if names is None:
        names = [name for name, value in vars(obj).items() if _is_state(value)]
    return names


def object_state(obj, names=None):
    """{attribute: copy of its value} of ``obj`` for the attribute ``names`` (default: its
    STATE, module docstring); {} for None."""
    if obj is None:
        return {}
    return {name: _value(getattr(obj, name)) for name in _names(obj, names)}


def restore_object(obj, state):
    """Put back what object_state(obj) returned, in its order; a property with a setter
    through that setter."""
    for name, saved in state.items():
        current = getattr(obj, name, None)  # a step solver sets some attributes at its first step
        if getattr(getattr(type(obj), name, None), "fset", None) is not None:
            setattr(obj, name, saved)
        elif hasattr(current, "x") and hasattr(current.x, "array"):
            current.x.array[:] = saved
        elif isinstance(current, np.ndarray) and isinstance(saved, np.ndarray) and current.shape == saved.shape \
                and current.dtype == saved.dtype:
            current[...] = saved
        elif isinstance(current, list) and isinstance(saved, list) and all(isinstance(s, dict) for s in saved) \
                and all(hasattr(item, "__dict__") for item in current):
            for item, item_state in zip(current, saved):
                restore_object(item, item_state)
        else:
            setattr(obj, name, saved)


def _copy_into(saved, value):
    """_value(value), written into ``saved`` (an earlier _value of it) where their arrays
    match, so that a mark made every step allocates nothing."""
    array = value.x.array if hasattr(value, "x") and hasattr(value.x, "array") else value
    if isinstance(array, np.ndarray) and isinstance(saved, np.ndarray) and saved is not array \
            and saved.shape == array.shape and saved.dtype == array.dtype:
        np.copyto(saved, array)
        return saved
    return _value(value)


class Rewind:
    """The state of ``objects`` kept in memory at ``mark()`` and put back by ``restore()``:
    the last completed step, for a step abandoned midway.

    An object's ``REWIND`` (attribute names), where it has one, replaces its STATE here: it
    leaves out what a checkpoint keeps but the object can do without (a cache), and the
    object's ``rewound()``, called after the restore, gives that up."""

    def __init__(self, objects):
        self.objects, self.states = objects, None

    def mark(self):
        before = self.states or [{} for _ in self.objects]
        self.states = [{} if obj is None else
                       {name: _copy_into(saved.get(name), getattr(obj, name))
                        for name in _names(obj, getattr(obj, "REWIND", None))}
                       for obj, saved in zip(self.objects, before)]

    def restore(self):
        for obj, state in zip(self.objects, self.states):
            restore_object(obj, state)
            if hasattr(obj, "rewound"):
                obj.rewound()


def owner_rule(centroids, comm):
    """mesh.build's owner_rule giving each cell to the rank that owned it when the checkpoint
    was written (DOLFINx's graph partitioner may split the same mesh differently from one
    run to the next): centroids (n, gdim) m, this rank's owned cells then. Collective."""
    parts = comm.allgather(np.asarray(centroids))
    tree = cKDTree(np.concatenate(parts))
    ranks = np.repeat(np.arange(len(parts)), [len(p) for p in parts])
    return lambda c: ranks[tree.query(c)[1]]


class _Unpickler(pickle.Unpickler):
    """Reads checkpoints written before the case's classes moved from dolfrag.config to the
    package dolfrag.case (sections.py), so that such a run still resumes."""

    def find_class(self, module, name):
        return super().find_class("dolfrag.case.sections" if module == "dolfrag.config" else module, name)


def _path(out, comm):
    return Path(out) / FOLDER / f"rank{comm.rank:05d}-of-{comm.size:05d}.pkl"


def _temporary(obj, path):
    """Pickle ``obj`` into path.tmp, on disk; return that path (renamed by the caller)."""
    tmp = path.with_suffix(".tmp")
    with open(tmp, "wb") as f:
        pickle.dump(obj, f, protocol=pickle.HIGHEST_PROTOCOL)
        f.flush()
        os.fsync(f.fileno())
    return tmp


def write(out, comm, data, case):
    """Write this rank's ``data`` (picklable) atomically, and the case.Case (rank 0).
    Collective: every rank has written its temporary file before any renames, so a stop in
    between leaves the previous checkpoint of every rank, or the new one of some (load
    tells by the step)."""
    path = _path(out, comm)
    if comm.rank == 0:
        path.parent.mkdir(exist_ok=True)
        os.replace(_temporary(case, path.parent / CASE), path.parent / CASE)
    comm.barrier()
    tmp = _temporary(data, path)
    comm.barrier()
    os.replace(tmp, path)
    comm.barrier()


def case_of(out):
    """The case.Case a checkpoint in ``out`` was written for. Raises CaseError when there
    is none."""
    path = Path(out) / FOLDER / CASE
    if not path.exists():
        raise CaseError(f"--resume {out}: no checkpoint in it ({path} is missing)")
    with open(path, "rb") as f:
        case = _Unpickler(f).load()
    if "bars_step" not in vars(case.time):
        # written before time.bars_step existed: stepped with the bars' "weyl" bound, which
        # its resumed run keeps (the default would change its step)
        case = dataclasses.replace(case, time=dataclasses.replace(case.time, bars_step="weyl"))
    return case


def ranks_of(out):
    """The rank counts a checkpoint in ``out`` was written on, sorted (empty: none there)."""
    return sorted(int(p.name.split("-of-")[1][:-4]) for p in (Path(out) / FOLDER).glob("rank00000-of-*.pkl"))


def load(out, comm):
    """This rank's checkpoint data. Collective. Raises CaseError (the same on every rank)
    when the rank count differs or the ranks' files are of different steps."""
    path = _path(out, comm)
    written = ranks_of(out)
    data = None
    if path.exists():
        with open(path, "rb") as f:
            data = _Unpickler(f).load()
    sizes = comm.allgather(None if data is None else data["step"])
    if None in sizes:
        raise CaseError(f"--resume {out}: the checkpoint was written on {', '.join(map(str, written))} "
                        f"rank(s); resume it with mpirun -n {written[0] if written else '?'} "
                        f"(this run has {comm.size})")
    if len(set(sizes)) > 1:
        raise CaseError(f"--resume {out}: the ranks' checkpoints are of different steps {sorted(set(sizes))} "
                        "(a stop while they were renamed); no consistent checkpoint to resume from")
    return data
