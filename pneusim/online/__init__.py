"""Online estimators: identification inside the sample loop, one sample at a time.

:class:`PaperRLS` is paper 1's recursive least squares (eq. 8) with h-step predictions, in C
(``_rls.pyx``); :class:`SysidRLS` runs the same recursion through :class:`sysid.RecursiveARX`;
:func:`make_rls` picks one; :func:`check_rls_settings` checks one's settings in a file against its run.
"""

from .rls import PaperRLS, SysidRLS, check_rls_settings, make_rls

__all__ = ["PaperRLS", "SysidRLS", "make_rls", "check_rls_settings"]
