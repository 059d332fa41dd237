"""Physics and timing of the line's three mechanisms: numpy only, no ROS.

Modules
-------
validate
    Checks shared by the frozen parameter dataclasses.
constants
    Standard gravity and machine epsilon, shared by the core and its effects.
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
chain
    D: the delivery chain's guide geometry (arc length over the stroke) and carriage
    schedule (carriage k takes sheet k); no friction.
belt
    Belts geared to the master drive, with slow-downs: exact travel and its inverse.
timebase
    Drift-free crank phase from integer nanoseconds.
pile
    The sheet counter's table (delivery pile or container floor), lowered by one sheet
    thickness per counted sheet.
"""
