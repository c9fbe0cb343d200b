"""Mismatch diagnosis (``shared/spec/diagnosis.md``): locate where a recording and the fitted nominal
model differ, name the physics left out from the vocabulary, model it, and show the fit improve on
data the fit never saw.

``diagnose(recording)`` returns a :class:`DiagnosisResult` whose ``to_dict()`` is the contract's JSON;
it runs :class:`Diagnosis`, an estimator whose stages (:class:`DiagnosisStages`) can be swapped one by one;
the thresholds that decide what is screened, fitted and kept are in :mod:`.rules`.
:func:`write_report` writes a result's report folder; :func:`diagnose_many` runs several recordings on the
sweep executor (local processes or Dask) and writes one summary table.
"""

from .diagnose import diagnose
from .estimator import Diagnosis, DiagnosisStages
from .result import CandidateTrial, DiagnosisResult, Finding, MismatchWindow

__all__ = ["diagnose", "Diagnosis", "DiagnosisStages", "DiagnosisResult", "Finding", "MismatchWindow",
           "CandidateTrial", "write_report", "diagnose_many"]


def write_report(result, folder):
    """Write the report folder of a diagnosis (``index.html``, ``report.md``, plots, ``diagnosis.json``)."""
    from .report import write_report as _write

    return _write(result, folder)


def diagnose_many(*args, **kwargs):
    """Diagnose several recordings on the sweep executor; see :func:`pneusim.diagnosis.batch.diagnose_many`."""
    from .batch import diagnose_many as _many

    return _many(*args, **kwargs)
