"""The paper's figures and the studies (not installed: run from the repository root).

``python -m experiments COMMAND PROBLEM`` (:mod:`experiments.__main__`) and
``python -m experiments.NAME [SETTINGS]`` for the studies with settings files of their own.
They import :mod:`mmstab`; nothing in :mod:`mmstab` imports them.
"""
