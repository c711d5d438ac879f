"""Reproductions of the source papers' experiments (``sensorgym reproduce NAME``).

Each public module here is the command line of one reproduction (``HELP``,
``add_arguments(parser)``, ``run(args)``), discovered by name (``bot_benchmark`` is run as
``bot-benchmark``); the experiment it runs — scenario, simulation, statistics, result dict and
report text — is the module of the same name in :mod:`sensorgym.reproduce.experiments`.
"""
