"""The line's one set of limits: each time span, rate and speed has one physical range.

The command line, the scene loader and the node parameters take their bounds from
here, so a value one of them accepts the others accept too, and one refusal reads the
same everywhere. Each range is physical, not an open interval: no subnormal, no
absurd value passes (``knife.n_k=1e-300`` would give one knife cycle in 10^296
years; ``1e308`` a cycle of 10^-301 s).

Every bound is inclusive. :data:`LIMITS` lists them for docs/limits.md and the tests.
"""

from __future__ import annotations

from dataclasses import dataclass

from folder_line.core.numerics.validate import as_float
from folder_line.errors import ParameterError

__all__ = [
    'BOUNCE_DECELERATION',
    'CARRIAGE_FORCE',
    'CRANK_SPEED',
    'CYLINDER_SPEED',
    'DURATION',
    'FRICTION_COEFFICIENT',
    'KNIFE_SPEED',
    'LIMITS',
    'LINEAR_SPEED',
    'LINE_DAMPING',
    'LOST_TIMEOUT',
    'MACHINE_LENGTH',
    'MOTOR_INERTIA',
    'MOTOR_SPEED',
    'MOTOR_TORQUE',
    'PILE_LOWERING',
    'REST_SPEED',
    'RTF',
    'SAMPLE_RATE',
    'SHEET_INTERVAL',
    'SPROCKET_RADIUS',
    'TICK_RATE',
    'Limit',
]


@dataclass(frozen=True)
class Limit:
    """One physical range, both ends inclusive.

    Attributes
    ----------
    what : str
        What is limited, for the table of docs/limits.md (``'line time of a run'``).
    lo, hi : float
        The range, in ``unit``.
    unit : str
        Unit of the bounds (empty for a ratio).
    why : str
        Where the bounds come from.
    """

    what: str
    lo: float
    hi: float
    unit: str
    why: str

    def check(self, key: str, value: object) -> float:
        """``value`` as a finite float inside the range; ``ParameterError`` naming ``key``, the value and the
        range with its unit otherwise."""
        x = as_float(key, value)
        if not self.lo <= x <= self.hi:
            raise ParameterError(key, value, f'must be in {self.text()}')
        return x

    @property
    def bounds(self) -> tuple[float, float]:
        """``(lo, hi)``, as node parameter specs take them."""
        return (self.lo, self.hi)

    def text(self) -> str:
        """``'[0.001, 10000000] s'``."""
        return f'[{self.lo:.10g}, {self.hi:.10g}] {self.unit}'.rstrip()


#: line time of a run or a simulation: from a millisecond to 1e7 s (116 days), where float64 time still
#: resolves 2 ns (the memory does not grow with it: the line is streamed)
DURATION = Limit(
    'line time of a run or a simulation (`--duration`, `line_clock` `duration`)',
    1e-3,
    1e7,
    's',
    'float64 line time resolves 2 ns up to 1e7 s',
)
TICK_RATE = Limit(
    'tick and joint-state rate in sim time (`line_clock` and node `rate`)',
    1.0,
    10000.0,
    'Hz',
    'a tick of 0.1 ms resolves the fastest event spacing (the feed window, ~0.3 ms); below '
    '1 Hz a tick spans several knife cycles',
)
RTF = Limit(
    'real-time factor ceiling (`--rtf`, `line_clock` `rtf`; 0 or `max`: none)',
    1e-3,
    1000.0,
    '',
    'from a thousand times slower than real time (stepping through a cycle) to a thousand times faster',
)
SAMPLE_RATE = Limit(
    'joint-state sample rate of the batch model (scene `sample_rate`; 0: events only)',
    0.0,
    1e6,
    'Hz',
    'a microsecond grid',
)
LOST_TIMEOUT = Limit(
    'wall time before a silent participant is declared lost (`--lost-timeout`)',
    0.1,
    3600.0,
    's',
    'longer than a tick can take on a loaded machine, shorter than an hour',
)
KNIFE_SPEED = Limit(
    'knife crank speed (`knife.n_k`; in a scene twice the folding cylinder speed)',
    2.0,
    200000.0,
    'rev/h',
    "the papers' folders run 25000-60000 rev/h; 2 rev/h (a cut every half hour) is slow motion, "
    '200000 rev/h a cycle of 18 ms',
)
CYLINDER_SPEED = Limit(
    'folding cylinder speed, the press speed (`cyclogram.n_c`, `press.n_c`)',
    1.0,
    100000.0,
    'rev/h',
    'the knife turns twice per cylinder turn (paper 001), so half the knife range',
)
CRANK_SPEED = Limit(
    'layup crank speed (`layup.n_kr`)',
    0.01,
    6000.0,
    'rev/min',
    'from one swing in 100 min to 100 swings a second (the paper: 30 rev/min)',
)
LINEAR_SPEED = Limit(
    'belt and transporter speeds (`feed_transporter.V_tr`; `layup.v_tr`, which may also be 0)',
    1e-3,
    1000.0,
    'm/s',
    'from a millimetre per second to ten times the fastest web press',
)
MOTOR_SPEED = Limit('motor shaft speed (`effects.motor_dynamics.omega_nom`)', 1e-3, 1e5, 'rad/s', 'up to ~1e6 rev/min')
PILE_LOWERING = Limit(
    'time the pile lift takes to lower one sheet (`pile.t_lower`, tunable live)',
    1e-3,
    10.0,
    's',
    'from a millisecond (a step) to a lift slower than any folder cycle',
)
SHEET_INTERVAL = Limit(
    'time between two sheets or leaves (`sheets.interval`)',
    1e-4,
    1e6,
    's',
    'from 10 000 sheets a second to one in 12 days (a long-run check with a few leaves)',
)
MACHINE_LENGTH = Limit(
    'a length of the folder or the delivery (`cyclogram.D_fc`, `cyclogram.L_feed`, `cyclogram.L_a`, '
    "`delivery_chain.x_max`, `knife.r_k`; the knife's rod and the offset of its stroke axis at most as long)",
    1e-4,
    100.0,
    'm',
    "from a tenth of a millimetre to a machine a hundred metres long (the papers': 0.08-1.2 m)",
)
SPROCKET_RADIUS = Limit(
    'radius of the delivery chain sprocket (`chain_friction.r`)',
    1e-3,
    10.0,
    'm',
    'a millimetre to ten metres: the sprocket turns at v_A / r, a motor speed',
)
BOUNCE_DECELERATION = Limit(
    'deceleration of a rebounding signature (`stop_bounce.a_f`)',
    1.0,
    1e6,
    'm/s²',
    'from a soft brush (a rebound of 0.5 m at 1 m/s) to a hard stop (0.5 µm)',
)
MOTOR_INERTIA = Limit(
    'inertia of the master shaft and all geared to it (`motor_dynamics.J`)',
    1e-6,
    1e5,
    'kg m²',
    'from a small servo rotor to a flywheel of tonnes; the time constant J / (T_0 / omega_0) must stay finite',
)
MOTOR_TORQUE = Limit(
    'stall torque of the motor (`motor_dynamics.T_0`)',
    1e-3,
    1e7,
    'N m',
    'from a toy motor to the largest industrial drives (~1e6 N m)',
)
LINE_DAMPING = Limit(
    'viscous load of the line on the master shaft (`motor_dynamics.b`)',
    0.0,
    1e5,
    'N m s',
    'none, up to a load that would brake 1e7 N m at 100 rad/s',
)
FRICTION_COEFFICIENT = Limit(
    'kinetic friction coefficient of the signature on the feed belt (`feed_slip.mu`)',
    1e-3,
    10.0,
    '',
    'from ice on steel to a gripping belt',
)
REST_SPEED = Limit(
    'speed below which an impact at the stops does not rebound (`stop_bounce.v_rest`)',
    1e-6,
    100.0,
    'm/s',
    'a micrometre per second to ten times the fastest belt: the rebounds are counted down to it',
)
CARRIAGE_FORCE = Limit(
    'useful force of a delivery carriage on the stroke (`chain_friction.P_k`)',
    0.0,
    1e6,
    'N',
    'none, to a hundred tonnes',
)

#: every limit, for the table of docs/limits.md and the tests
LIMITS: dict[str, Limit] = {
    'duration': DURATION,
    'rate': TICK_RATE,
    'rtf': RTF,
    'sample_rate': SAMPLE_RATE,
    'lost_timeout': LOST_TIMEOUT,
    'knife_speed': KNIFE_SPEED,
    'cylinder_speed': CYLINDER_SPEED,
    'crank_speed': CRANK_SPEED,
    'linear_speed': LINEAR_SPEED,
    'motor_speed': MOTOR_SPEED,
    'pile_lowering': PILE_LOWERING,
    'sheet_interval': SHEET_INTERVAL,
    'machine_length': MACHINE_LENGTH,
    'sprocket_radius': SPROCKET_RADIUS,
    'bounce_deceleration': BOUNCE_DECELERATION,
    'motor_inertia': MOTOR_INERTIA,
    'motor_torque': MOTOR_TORQUE,
    'line_damping': LINE_DAMPING,
    'friction_coefficient': FRICTION_COEFFICIENT,
    'rest_speed': REST_SPEED,
    'carriage_force': CARRIAGE_FORCE,
}
