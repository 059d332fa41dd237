"""Replay analysis of a recorded run (``folder-line analyze``), without ROS: the bag is read with rosbags.

The modules, in the order the data flows:

:mod:`~folder_line.analysis.recording`
    a run directory or a bag decoded into a :class:`Recording` (:func:`read_recording`);
:mod:`~folder_line.analysis.replay`
    the recorded events judged by the line's constraint code (:func:`evaluate`), window by window
    of line time;
:mod:`~folder_line.analysis.event_check`
    the recorded events compared with the streamed line model's (:func:`compare_events`), window
    by window;
:mod:`~folder_line.analysis.supervisor_replay`
    the supervisor's logic replayed on the recorded inputs (:func:`replay_transitions`);
:mod:`~folder_line.analysis.streaming`
    what the figures show of a whole run, gathered as the windows pass in bounded memory (a
    binned margin histogram, a hash-thinned sample);
:mod:`~folder_line.analysis.figure_data` and :mod:`~folder_line.analysis.figures`
    what each figure shows, as arrays, and the figures drawn (with the papers' model
    curves of :mod:`~folder_line.analysis.paper_curves` that ``folder-line report`` draws too,
    in the colours of :mod:`~folder_line.analysis.colours`);
:mod:`~folder_line.analysis.csv_export`
    every message of the bag as CSV, one file per topic (a ``t`` column in s, events parsed,
    diagnostics one row per status), streamed;
:mod:`~folder_line.analysis.report`
    :func:`analyze`: ``report.md``, the figures and the CSVs written; :func:`print_analysis`.
"""

from folder_line.analysis.csv_export import CsvCollector, csv_name, flatten_message, message_rows
from folder_line.analysis.event_check import EventCheck, compare_events
from folder_line.analysis.figure_data import (
    GANTT_CYCLES,
    cycle_rows,
    efficiency_data,
    exit_speed_data,
    landing_data,
    leaf_exit_data,
)
from folder_line.analysis.figures import FIGURES, draw_figures
from folder_line.analysis.recording import RecordedJoints, Recording, read_recording
from folder_line.analysis.replay import Evaluation, evaluate
from folder_line.analysis.report import AnalysisResult, analyze, print_analysis
from folder_line.analysis.supervisor_replay import (
    KEY_SUPERVISOR,
    SUPERVISOR_DEFAULTS,
    recorded_transitions,
    replay_transitions,
    supervisor_parameters,
    transitions_agree,
)

__all__ = [
    'FIGURES',
    'GANTT_CYCLES',
    'KEY_SUPERVISOR',
    'SUPERVISOR_DEFAULTS',
    'AnalysisResult',
    'CsvCollector',
    'Evaluation',
    'EventCheck',
    'RecordedJoints',
    'Recording',
    'analyze',
    'compare_events',
    'csv_name',
    'cycle_rows',
    'draw_figures',
    'efficiency_data',
    'evaluate',
    'exit_speed_data',
    'flatten_message',
    'landing_data',
    'leaf_exit_data',
    'message_rows',
    'print_analysis',
    'read_recording',
    'recorded_transitions',
    'replay_transitions',
    'supervisor_parameters',
    'transitions_agree',
]
