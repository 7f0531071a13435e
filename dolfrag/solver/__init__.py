"""Time integrators: solver/imex.Imex and solver/theta.Theta, both Integrators."""
from typing import Protocol


class InterfaceReport(Protocol):
    """What an integrator's interface step tells the run after each step: its Newton
    iterations, the largest final scaled residual (-), the star solves left unconverged and
    those accepted stalled (imex's star solver; 0 otherwise), the energy the contact
    reactions dissipated so far on this rank's links (J, J/m in 2D); layout: the star layout
    a checkpoint keeps, None for a solver without one; failed: the unconverged stars'
    kernel inputs (solver/star_replay.py) when the last step had some, else None."""
    iterations: int
    residual: float
    unconverged: int
    stalled: int
    contact_dissipated: float
    layout: object
    failed: object


class Integrator(Protocol):
    """What the run (runner/) asks of a time integrator.

    u, v: displacement (m) and velocity (m/s) Functions; m: the lumped mass of every local
    dof component (kg); t (s) and n: time and steps done; h: the time step (s); pressure:
    p(t) (Pa); model: the interface model (interface/models.py); interface: the
    InterfaceReport of the last step; rebars: rebar/cables.Rebars or None; viscosity:
    viscosity.BulkViscosity or None; timer: timing.PhaseTimer; abandonable: whether a stop
    request set as ``interrupt`` can abandon a step midway (solver/interrupt.py)."""
    u: object
    v: object
    m: object
    t: float
    n: int
    h: float
    pressure: object
    model: object
    interface: InterfaceReport
    rebars: object
    viscosity: object
    timer: object
    abandonable: bool
    interrupt: object

    @property
    def energy_time(self) -> float:
        """Time (s) of the Energies step() returns."""

    def step(self, energies=False):
        """Advance one step; with ``energies`` return its solver/energy.Energies (collective),
        else None."""
