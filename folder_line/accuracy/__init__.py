"""``folder-line bench accuracy``: what each accuracy knob costs in CPU time.

Every study measures, for one method at one knob setting, the error against a checked
reference (closed form, or mpmath at high precision) and the CPU time per simulated
second, and returns :class:`~folder_line.accuracy.measure.Row` s. The studies:

``linkage``     six-bar rocker angle/velocity: closed form, Newton loop closure, finite differences
``fourbar``     a four-bar's rocker angle: closed form vs ``scipy.integrate.solve_ivp``
``motor``       the ``motor_dynamics`` ODE: RK4 at h, DOPRI5 and ``solve_ivp`` RK45/DOP853 at rtol
``events``      event times: sampling at a rate vs root finding
``publishing``  a JointState stream reconstructed by interpolation vs its cost in the live line

This package is an adapter (it may use scipy and mpmath); the physics it measures is
:mod:`folder_line.core`.
"""
