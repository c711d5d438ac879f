"""The reproductions' experiments, one module per paper or benchmark: scenario, simulation,
statistics, result dict and report text (tests import them from here).

The command line of each (``sensorgym reproduce NAME``) is the module of the same name in
:mod:`sensorgym.reproduce`.
"""
