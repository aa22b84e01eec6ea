"""Looking at simulated data: the torque-derived ground force against the engine's (``forces``)
and pictures of a logged jump (``render``)."""
