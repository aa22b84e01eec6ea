"""Simulation, by job, each layer importing only those below it: the engines (``engines``:
the ``World`` protocol, PyBullet, MuJoCo, the registry), the hardware-like variant and domain
randomisation (``proxy``), the controllers and motion plug-ins (``controllers``), generation of
datasets with the one episode loop (``generation``), and diagnostics of generated data
(``diagnostics``). See docs/design.md, "Simulation"."""
