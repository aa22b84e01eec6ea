"""Simulated datasets: the one episode loop (``episode``), a generated file's configuration
(``config``), the checks every kept jump passes (``checks``), one checked jump (``runner``), part
files (``parts``), the whole file (``generate``) and the workers' warm start (``warm``)."""
