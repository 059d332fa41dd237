"""Configuration, one path from a file to a validated object (no ROS).

* :mod:`~folder_line.config.params`: the default parameters in ``config/<machine>.yaml`` and
  ``folder-line kinematics``' ``--params`` files;
* :mod:`~folder_line.config.scenes`: scene files merged with the defaults and the ``KEY=VALUE``
  overrides, parsed once into a :class:`folder_line.core.line.scene.Scene`; the merged scene
  written for the nodes (``<out>/scene.yaml``) and shared by the nodes of a process;
* :mod:`~folder_line.config.run_config`: what ``folder-line run`` runs, the parameters it gives
  each node, the run folder's layout and the supervisor's defaults.

Every mapping becomes a frozen dataclass through one builder,
:func:`folder_line.core.numerics.validate.build`.
"""
