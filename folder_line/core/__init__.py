"""Physics and timing of the line's three mechanisms: numpy only, no ROS.

Modules
-------
validate
    Checks shared by the frozen parameter dataclasses.
loop
    Planar loop-closure primitives (circle-circle intersection, branches, toggles).
layup
    L: crank-rocker six-bar swinging two chutes (paper 000).
layup_paper
    L: the paper's projection-theorem formulas, kept only as a cross-check.
knife
    F: crank-slider folding knife.
cyclogram
    F: cycle timing of feed and knife (paper 001).
delivery
    D: chain-and-carriage delivery transporter efficiency (paper 002).
timebase
    Drift-free crank phase from integer nanoseconds.
"""
