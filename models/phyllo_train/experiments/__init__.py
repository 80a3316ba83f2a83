"""Tools of experiments that have ended; their results and commands are in models/EXPERIMENTS.md.

Kept runnable (``python -m phyllo_train.experiments.NAME``) and tested, so a finding can be
reproduced; nothing in the core, the modes or the tools imports them.
"""
