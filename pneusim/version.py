"""The version of pneusim, written into recordings and reports (``generator``) and printed by ``--version``."""

__version__ = "0.1.0"
