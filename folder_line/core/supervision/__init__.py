"""The supervisor's decisions — PackML state, constraint enforcement, liveness — pure, no ROS.

The lockstep ledger of the live line (:mod:`~folder_line.core.supervision.lockstep`) lives here too.

The modules of the supervisor's logic:

* :mod:`~folder_line.core.supervision.supervisor`: :class:`Supervisor`, its inputs, ticks and
  decisions (time and determinism; what each violation leads to);
* :mod:`~folder_line.core.supervision.settings`: :class:`Settings`, the parameters, checked once;
* :mod:`~folder_line.core.supervision.evaluation`: cycle evaluation, each constraint judged at
  its own decision time by the batch simulator's code;
* :mod:`~folder_line.core.supervision.liveness`: which watched participant has gone silent;
* :mod:`~folder_line.core.supervision.commands`: command scheduling (the drive commands, their
  effective times, the line model under them) and the end of acting states;
* :mod:`~folder_line.core.supervision.grid`: the check grid ``t = n h``;
* :mod:`~folder_line.core.supervision.balance`: the sheet balance at a stop;
* :mod:`~folder_line.core.supervision.records`: violations, per-constraint figures (what
  ``/diagnostics`` reports), answers to operator commands;
* :mod:`~folder_line.core.supervision.offline`: :func:`replay` and :func:`run_closed_loop`;
* :mod:`~folder_line.core.supervision.packml`: the PackML state machine.

:class:`Supervisor` is fed incrementally with what the live supervisor node sees and
advanced by ticks; it decides the PackML transitions and the drive commands to issue,
records every constraint violation and checks the sheet balance at every stop.
:func:`replay` runs the same object over a recorded stream offline and reproduces the
live run's transitions exactly.
"""
