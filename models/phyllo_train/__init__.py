"""phyllo_train: training, export and reference tooling for the phyllo leaf-counting network.

The single source of truth for tensor names, classes, label encoding and
normalisation is ``models/contract.toml``; see :mod:`phyllo_train.contract`.
"""

__version__ = "0.1.0"
