"""The physics engines behind one protocol: engine-neutral types and the ``World`` protocol
(``world``), one module per engine (``bullet``: PyBullet, ``mujoco``: MuJoCo), their compiled
state reads (``compiled``) and the registry that imports an engine only when a world of it is
made (``registry``)."""
