"""Train's modes that are off by default, one flag each (the core, :mod:`phyllo_train.train`, imports them).

``ddp``: ``--procs N`` splits one CPU run over N single-threaded processes;
``distill``: ``--teacher`` replaces the side views' centre targets with a teacher's heatmaps;
``photometric_torch``: ``--photometric device`` applies the photometric augmentation
batched on the training device instead of in the loaders.
"""
