"""The colours of the figures: one colour per quantity, in every figure that draws it.

``folder-line report`` (:mod:`folder_line.cli.report`) and ``folder-line analyze``
(:mod:`folder_line.analysis.figures`) both take their colours from here, so that ``η_A``
is the same colour in the report's ``delivery_efficiency.png`` and in a run's
``efficiency.png``, and ``v_C`` the same in ``layup_speeds.png`` and ``exit_speeds.png``.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

__all__ = ['PHASE_COLOURS', 'QUANTITY_COLOURS']

#: quantity -> its matplotlib colour; the keys are the names the figures' code uses
QUANTITY_COLOURS: Mapping[str, str] = MappingProxyType(
    {
        # L: the layup's exits (paper L, figs. 4-5)
        'vC': 'tab:blue',  # v_C, v_aC and the recorded omega_3 l_3 (exit of transporter 3)
        'vE': 'tab:orange',  # v_E, v_aE and the recorded omega_5 l_5 (exit of transporter 4)
        'vC_no_belts': 'tab:green',  # |v_C| without belts
        'leaf_exit_C': 'tab:red',
        'leaf_exit_E': 'tab:purple',
        'start_up': 'tab:gray',  # recorded samples before the drive reached speed
        # D: the delivery (paper D, fig. 2): eta and K_v per return-section mode, the pair eta_A, eta_B
        'paper_mirror': 'tab:blue',
        'geometric': 'tab:orange',
        'eta_A': 'tab:green',
        'eta_B': 'tab:red',
        'torque': 'tab:olive',  # model sprocket torque M_1
        'release': 'tab:purple',  # stroke position of the release on the pile
    }
)

#: colours of the cyclogram's phases (knife over the table, feed, dwell at the stops)
PHASE_COLOURS: Mapping[str, str] = MappingProxyType({'knife': 'tab:red', 'feed': 'tab:green', 'dwell': 'tab:blue'})
