"""A distributed sparse linear system of fixed pattern and its direct solver (PETSc KSP):
the linear algebra of the theta step, apart from its physics and its Newton policy.

The pattern is given once as blocks of global (row, column) entries, each entry possibly
dropped (a held dof component, a frozen link component on either side); values are then
given in the same block order. Rows are owned by the rank whose range holds them;
off-process entries go through PETSc's assembly. No option is written to PETSc's global
options database: the solver reads it under the prefix ``dolfrag_theta_``, and MUMPS'
workspace relaxation is set on the factor itself.
"""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

KSP_REASONS = {getattr(PETSc.KSP.ConvergedReason, k): k for k in dir(PETSc.KSP.ConvergedReason)
               if not k.startswith("_")}
MUMPS_WORKSPACE = 20  # %: MUMPS' default relaxation ICNTL(14), unless the options database says otherwise


class LinearSolveError(Exception):
    """A factorisation or solve that failed; the message says why."""


class SparseSystem:
    """blocks: {name: (rows, cols, dropped)} global indices (any shape, alike per block);
    n_local, start: this rank's rows and its first global row; factor: "lu" (MUMPS' pivoting
    LU, for saddle points), "cholesky" or "lu-nonsymmetric" (PETSc's own factor serially,
    MUMPS in parallel); relaxations: doublings of MUMPS' workspace tried when a factorisation
    runs short of it. Collective."""

    def __init__(self, comm, blocks, n_local, start, factor, relaxations):
        self.comm, self.relaxations = comm, relaxations
        self.names = list(blocks)
        rows = np.concatenate([b[0].ravel() for b in blocks.values()])
        cols = np.concatenate([b[1].ravel() for b in blocks.values()])
        self._keep = ~np.concatenate([b[2].ravel() for b in blocks.values()])
        size = self.size = comm.allreduce(n_local)
        key, self._slot = np.unique(rows * size + cols, return_inverse=True)
        self._rows, self._cols = key // size, key % size
        ranges = np.array(comm.allgather(start) + [size])
        d_nnz, o_nnz = _preallocation(comm, self._rows, self._cols, ranges)
        A = PETSc.Mat().createAIJ(size=((n_local, size), (n_local, size)), nnz=(d_nnz, o_nnz), comm=comm)
        A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
        rowmap, count = np.unique(self._rows, return_counts=True)
        self._csr = (np.r_[0, np.cumsum(count)].astype(PETSc.IntType), self._cols.astype(PETSc.IntType),
                     rowmap.astype(PETSc.IntType))
        self.A = A
        self.ksp = self._solver(factor)
        self._workspace = PETSc.Options(self.ksp.getOptionsPrefix()).getInt("mat_mumps_icntl_14", MUMPS_WORKSPACE)
        self._factor_ready = False  # the factor exists once A has values
        self._rhs, self._dz = A.createVecs()
        self._last_values = None

    def _solver(self, factor):
        ksp = PETSc.KSP().create(self.comm)
        ksp.setOperators(self.A)
        ksp.setType("preonly")
        pc = ksp.getPC()
        if factor == "lu":
            pc.setType("lu")
            pc.setFactorSolverType("mumps")
        else:
            pc.setType("cholesky" if factor == "cholesky" else "lu")
            # serial: PETSc's own factor solves 4x faster than MUMPS (10 against 40 ms at
            # 72k unknowns, measured); in parallel MUMPS is the distributed one
            pc.setFactorSolverType("petsc" if self.comm.size == 1 else "mumps")
            if self.comm.size == 1:
                pc.setFactorOrdering("nd")
        ksp.setOptionsPrefix("dolfrag_theta_")
        ksp.setFromOptions()
        return ksp

    def _set_workspace(self, pc):
        if pc.getFactorSolverType() == "mumps":
            pc.setFactorSetUpSolverType()
            pc.getFactorMatrix().setMumpsIcntl(14, self._workspace)

    def assemble(self, values):
        """Set the matrix to ``values`` ({block name: entries shaped as the block's indices},
        dropped entries included); the next solve refactorises. Nothing is done when no entry
        changed on any rank. Collective."""
        flat = np.concatenate([values[name].ravel() for name in self.names])
        summed = np.bincount(self._slot, weights=flat * self._keep, minlength=len(self._rows))
        changed = self._last_values is None or not np.array_equal(summed, self._last_values)
        if self.comm.allreduce(changed, op=MPI.LOR):
            self.A.zeroEntries()
            self.A.setValuesIJV(*self._csr[:2], summed, addv=PETSc.InsertMode.ADD_VALUES, rowmap=self._csr[2])
            self.A.assemble()
            self._last_values = summed
            if not self._factor_ready:
                self._set_workspace(self.ksp.getPC())
                self._factor_ready = True

    def forget(self):
        """Drop the memory of the last values: the next assemble sets them whatever they are."""
        self._last_values = None

    def solve(self, rhs):
        """The solution of A z = rhs (owned rows); LinearSolveError if the factorisation or
        the solve failed (after relaxations of MUMPS' workspace where that was short).
        Collective."""
        self._rhs.array[:] = rhs
        for _ in range(self.relaxations + 1):
            try:
                self.ksp.solve(self._rhs, self._dz)
            except PETSc.Error as err:
                self.forget()
                raise LinearSolveError(f"linear solve failed: {err}") from None
            reason = self.ksp.getConvergedReason()
            if reason >= 0 or not self._short_of_workspace():
                break
        if reason < 0:
            self.forget()
            raise LinearSolveError(f"linear solve failed: {KSP_REASONS.get(reason, reason)}")
        return self._dz.array.copy()

    def _short_of_workspace(self):
        """After a failed factorisation: if MUMPS ran out of workspace (INFOG(1) = -8, -9:
        pivots delayed by nearly redundant constraints, e.g. all links of a rigid law
        sticking at t = 0), double its workspace relaxation ICNTL(14) and return True: the
        next solve factorises anew. Collective."""
        pc = self.ksp.getPC()
        if pc.getFactorSolverType() != "mumps" or pc.getFactorMatrix().getMumpsInfog(1) not in (-8, -9):
            return False
        self._workspace *= 2
        pc.reset()  # forgets the factor and the operators
        self.ksp.setOperators(self.A)
        self.ksp.setFromOptions()
        self._set_workspace(pc)
        return True


def _preallocation(comm, rows, cols, ranges):
    """Nonzeros per owned row in the diagonal and off-diagonal blocks, for entries
    (rows, cols) given by any rank (each rank sends the owners theirs). Collective."""
    rank = comm.rank
    if comm.size > 1:
        owner = np.searchsorted(ranges, rows, side="right") - 1
        got = comm.alltoall([np.stack([rows[owner == k], cols[owner == k]]) for k in range(comm.size)])
        pairs = np.unique(np.concatenate(got, axis=1), axis=1)
        rows, cols = pairs
    start, stop = ranges[rank], ranges[rank + 1]
    local = rows - start
    diagonal = (cols >= start) & (cols < stop)
    n = stop - start
    return (np.bincount(local[diagonal], minlength=n).astype(PETSc.IntType),
            np.bincount(local[~diagonal], minlength=n).astype(PETSc.IntType))
