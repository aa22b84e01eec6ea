"""The controllers and the motions they make: the ``Controller`` and ``Motion`` protocols and
the plug-in loader (``motion``), a logged jump's flights (``flight``), the controllers' model of
the robot (``body``, fed by a ``BodySource``: ``urdf_body``), the convex MPC (``mpc``), the pronk
and froggy plug-ins and their compiled arithmetic (``compiled``)."""
