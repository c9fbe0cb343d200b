"""Look-alikes of physics outside the vocabulary: a finding is named only where it explains what it acts on.

When something the vocabulary has no name for is missing, a vocabulary effect can still lower the cost: a load
takes up part of a port's asymmetric flow, a spring part of a sensor's bowed reading.  It passes the keep test
(the model is less wrong with it) and drop-one (it is less wrong with it whatever else is in), and would be
reported under a name it does not deserve.  What tells the two apart is *where* the residual goes:

* a vocabulary effect that is right takes the residual down to the noise where it acts -- it models that
  physics, and nothing else is missing there;
* a look-alike leaves structured residual in the same stretches: it bends its own law towards the missing
  physics and takes part of it, never all (a constant force cannot follow a ratio of conductances).

So, where the model with every finding still leaves physics unexplained (:func:`.other.unexplained`), each
finding is checked where it acts: the stretches where the model without it misses beyond the noise (the
locate step's windowed mean square above its chi-square threshold) and the finding takes away at least
:data:`~.rules.ACTS_SHARE` of that.  Where the model with every finding still misses beyond the noise over more
than :data:`~.rules.LEFT_SHARE` of those samples, the finding is a look-alike: it is taken out of the model (the
others refitted without it, as drop-one did) and the residual is reported as ``other``.  A model that
explains the recording down to the noise has nothing to hide, and is not checked.
"""

from __future__ import annotations

import numpy as np

from .locate import named_states, window_threshold, windowed_mean_squares
from .other import unexplained
from .rules import ACTS_SHARE, LEFT_SHARE

__all__ = ["residual_left", "name_only_what_explains"]


def residual_left(run, final, without) -> tuple[float, int]:
    """``(share, samples)``: of the samples where the finding acts (``without``: the model without it; ``final``:
    with it, see the module docstring), the share where ``final`` still misses beyond the noise, and how many
    samples that is (0: it acts nowhere beyond the noise)."""
    m, threshold = window_threshold(run.recording)
    with_it = windowed_mean_squares(run.recording, named_states(final), run.noise, m)
    without_it = windowed_mean_squares(run.recording, named_states(without), run.noise, m)
    acts, left = np.zeros(run.recording.n_samples, bool), np.zeros(run.recording.n_samples, bool)
    for name, before in without_it.items():
        after = with_it[name]
        here = (before > threshold) & (before - after >= ACTS_SHARE * before)
        acts |= here
        left |= here & (after > threshold)
    n = int(acts.sum())
    return (float(left.sum()) / n if n else 0.0), n


def name_only_what_explains(run, final, importance: dict):
    """Take out of ``final`` every finding that leaves the residual where it acts (:func:`residual_left` above
    :data:`~.rules.LEFT_SHARE`), least important first, while the model leaves physics unexplained; returns
    ``(final, taken out)``.  The model without a finding is drop-one's fit (``run.fits_without``), the nominal fit
    for a lone finding; the trials say why."""
    out = []
    while final.effects_ and unexplained(final, run.noise, run.baseline.floor)[0]:
        judged = []
        for e in final.effects_:
            without = run.fits_without.get(e.name) if len(final.effects_) > 1 else run.baseline.fit
            if without is None:
                continue
            share, n = residual_left(run, final, without)
            judged.append((share, e.name, without, n))
        flagged = [j for j in judged if j[0] > LEFT_SHARE]
        if not flagged:
            break
        share, name, without, n = min(flagged, key=lambda j: importance.get(j[1], 0.0))
        run.trials[name].kept = False
        run.trials[name].status += (f"; a look-alike: where it acts ({n} samples where the model without it misses "
                                    f"beyond the noise), the model with it still does over {100 * share:.0f} % of "
                                    "them -- it takes part of what is missing, not all: not named")
        out.append(name)
        run.say(f"{name} is taken out: it leaves {100 * share:.0f} % of where it acts above the noise")
        final = without
        run.fits_without = {}
    return final, out
