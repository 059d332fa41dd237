"""Tables of one mechanism over its cycle: the ``folder-line kinematics`` verb.

Columns and units are a contract (other checks read these CSVs):

* layup: ``phi, xC, yC, xE, yE, omega3, omega5, vC, vE, vaC, vaE`` over one
  crank turn, phi = 2*pi*i/N for i = 0..N-1 (rad, m, rad/s, m/s);
* knife: ``phi, s, v, a, in_window`` over one crank turn (rad, m, m/s, m/s^2, 0/1);
* delivery: ``xi, alpha, beta, Kv, eta_O, eta_A, eta_B, eta, state`` for
  xi = i/(N-1) in [0, 1] (rad; state is ``ok``, ``self_locking``, ``kv_zero``).
"""

from __future__ import annotations

import math
from typing import IO, Any

import numpy as np

from folder_line.config.params import load_params
from folder_line.core.line.scene import MachineParams
from folder_line.core.mechanisms import delivery, knife, layup

__all__ = ['COLUMNS', 'kinematics_table', 'print_summary']

COLUMNS: dict[str, tuple[str, ...]] = {
    'layup': ('phi', 'xC', 'yC', 'xE', 'yE', 'omega3', 'omega5', 'vC', 'vE', 'vaC', 'vaE'),
    'knife': ('phi', 's', 'v', 'a', 'in_window'),
    'delivery': ('xi', 'alpha', 'beta', 'Kv', 'eta_O', 'eta_A', 'eta_B', 'eta', 'state'),
}


def _params(mechanism: str, params_path: str | None, params: MachineParams | None) -> Any:
    return params if params is not None else load_params(mechanism, params_path)


def _turn(n: int) -> np.ndarray:
    return 2.0 * math.pi * np.arange(n, dtype=float) / n


def kinematics_table(
    mechanism: str, params_path: str | None, n: int, params: MachineParams | None = None
) -> dict[str, np.ndarray]:
    """Columns of the table of ``mechanism`` with ``n`` samples (see module doc).

    ``params``, if given, are the mechanism's validated parameters (``params_path`` is then not read);
    else they are the defaults with ``params_path``'s values.

    Raises
    ------
    ParameterError, AssemblyError
        Bad parameters (named key and value) or a geometry that does not assemble.
    """
    if mechanism == 'layup':
        phi = _turn(n)
        lay = layup.LayupModel(_params('layup', params_path, params)).arrays(phi, accelerations=False)
        return {name: np.asarray(getattr(lay, name)) for name in COLUMNS['layup']}
    if mechanism == 'knife':
        phi = _turn(n)
        kn = knife.state(_params('knife', params_path, params), phi)  # array phi: array fields (asarray: no copy)
        return {
            'phi': phi,
            's': np.asarray(kn.s),
            'v': np.asarray(kn.v),
            'a': np.asarray(kn.a),
            'in_window': np.asarray(kn.occupies).astype(np.int8),
        }
    if mechanism == 'delivery':
        xi = np.linspace(0.0, 1.0, n)
        ev = delivery.evaluate(_params('delivery', params_path, params), xi)
        return {
            'xi': xi,
            'alpha': ev.alpha,
            'beta': ev.beta,
            'Kv': ev.K_v,
            'eta_O': ev.eta_O,
            'eta_A': ev.eta_A,
            'eta_B': ev.eta_B,
            'eta': ev.eta,
            'state': ev.state_names(),
        }
    load_params(mechanism, params_path)  # an unknown kind or bad parameters: the ParameterError first
    msg = f'mechanism={mechanism!r}: must be one of {", ".join(COLUMNS)}'
    raise ValueError(msg)


def print_summary(mechanism: str, table: dict[str, np.ndarray], out: IO[str]) -> None:
    """One line per numeric column: min and max (and the state counts for delivery)."""
    n = len(next(iter(table.values())))
    print(f'{mechanism}: {n} samples', file=out)
    for name, col in table.items():
        arr = np.asarray(col)
        if arr.dtype.kind in 'fi':
            print(f'  {name:>9}  min {arr.min(): .6g}  max {arr.max(): .6g}', file=out)
        else:
            values, counts = np.unique(arr, return_counts=True)
            summary = ', '.join(f'{v}: {c}' for v, c in zip(values.tolist(), counts.tolist(), strict=True))
            print(f'  {name:>9}  {summary}', file=out)
