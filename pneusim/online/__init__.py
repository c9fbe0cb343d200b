"""Online estimators: identification inside the sample loop, one sample at a time.

:class:`PaperRLS` is paper 1's recursive least squares (eq. 8) with h-step predictions, in C
(``_rls.pyx``); :class:`SysidRLS` runs the same recursion through :class:`sysid.RecursiveARX`;
:func:`make_rls` picks one.
"""

from .rls import PaperRLS, SysidRLS, make_rls

__all__ = ["PaperRLS", "SysidRLS", "make_rls"]
