"""Training wrappers built on an env's rules: SB3 ``VecEnv`` wrappers that change a policy's
action into the rules' language (a choice among planned candidates, a correction of a planned
target, a scan mode) or add planners' features to its observation.

One module per env package, named after it; :data:`sensorgym.train.wrappers.WRAPPERS` names
each wrapper as a recipe's YAML does (``pointing-plan``, ``placement-target``, ``scan-modes``,
…). They sit above the envs and the rules (``envs ← agents ← train``): an env never imports
them.
"""
