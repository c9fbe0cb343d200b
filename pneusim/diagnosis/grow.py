"""Far above noise: several effects chosen together on the window, by forward selection of pre-fits.

A worn rig has a dead band *and* a leak *and* asymmetric seals at once.  Each effect alone explains part of
what the nominal model misses; fitted alone from the data sheet it bends the nominal parameters to make up
for the others, and a second effect tried on top of that bent fit is judged in the wrong basin.  So the
effects are chosen together, as a set, on the window where the nominal model misses most
(:func:`.from_data_sheet.mismatch_window`), where every candidate was already pre-fitted alone
(:func:`.from_data_sheet.screen_from_data_sheet`).  The candidates are *items*: each effect by its best
screened start, and each of its variants that is other physics (a leak's paths) on its own.

1. A set starts from one of the :data:`~.rules.GROW_STARTS` best-screened items, pre-fitted again with
   :data:`~.rules.GROW_EVALUATIONS` evaluations (sets are compared by where their pre-fits end);
2. every item of another effect among the :data:`~.rules.GROW_POOL` best screened alone (and the variants of
   other physics of their effects, whatever their score alone) is pre-fitted *with the set*, from the data
   sheet, the set's members at their pre-fitted values and the new effect at its start -- not from where the
   set's pre-fit left the nominal parameters, which bent to make up for what the set lacks -- and so is the
   set alone, again: a candidate's gain is then what it explains, not what the same steps find without it;
3. the one that lowers the window's cost most joins when it pays: the information criterion drops
   (``N ln(C_set / C_with) > k ln N``) *and* it takes away at least :data:`~.rules.GROW_SHARE` of what the
   set leaves above the noise (a flexible law takes a little from any structured residual, and far above
   noise the criterion alone lets nearly every candidate in).  Every cost compared is what the pre-fit
   minimised: its residuals *and* its continuity defects (:func:`cost`): an effect with unmeasured states of
   its own (chamber temperatures, a spool, a supply volume) lowers the residuals by opening its states'
   defects segment by segment (``docs/decisions/0034``);
4. a member with variants of other physics (a leak's path) is then tried as each other variant (screened well
   or not: a path alone may explain nothing that it explains beside another effect), the rest of the set
   present, and the better kept;
5. again from 2., while the set's pre-fit ends above :data:`~.rules.GROW_UNTIL` times the noise and holds
   fewer than ``run.max_findings`` effects;
6. of the sets grown from each start the better wins (the effect that explains most alone may be a look-alike
   of two others together): of two as large the lower cost, a larger one only where it pays against the
   smaller as a joining effect must; a transport delay in it (which no pre-fit moves: it has no gradient) is
   scanned by pre-fits of the set (:func:`.delay.scan_on_window`).

A pre-fit costs seconds where a whole fit costs a minute: the set is then fitted whole once (:mod:`.joint`),
what it leaves is looked for on top of that fit (:mod:`.findings`), and each member is tested with the others
present (drop-one).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..model import make_effect
from .candidates import Candidate
from .delay import DELAY, scan_on_window
from .from_data_sheet import data_sheet_start
from .refits import effect_at_prefit
from .rules import (GROW_EVALUATIONS, GROW_POOL, GROW_SHARE, GROW_STARTS, GROW_UNTIL, PREFIT_DEFECT_WEIGHT,
                    WINDOW_SAMPLES, bic_penalty, is_solver_failure)

__all__ = ["WindowSet", "window_items", "grow_on_window", "set_effects", "nominal_values", "cost"]


@dataclass
class WindowSet:
    """A set of effects chosen on the window: ``members`` (effect names, in the order they joined),
    ``candidates`` (``{effect: Candidate}``), ``prefit`` (the set's pre-fit on the window,
    :class:`~pneusim.fit.PrefitResult`), ``log`` (``{effect: what the growth said of it}``)."""

    members: list = field(default_factory=list)
    candidates: dict = field(default_factory=dict)
    prefit: object = None
    log: dict = field(default_factory=dict)

    @property
    def rms(self) -> float:
        """The set's pre-fit cost on the window as an rms, noise units (infinity before any pre-fit)."""
        if self.prefit is None:
            return math.inf
        return math.sqrt(cost(self.prefit) / max(self.prefit.n_residuals, 1))

    def criterion(self) -> float:
        """The set's information criterion on the window, ``N ln C + k ln N`` (lower is better)."""
        n = max(self.prefit.n_residuals, 2)
        k = sum(c.n_added for c in self.candidates.values())
        return n * math.log(max(cost(self.prefit), 1e-300)) + bic_penalty(k, n)


def nominal_values(prefit) -> dict:
    """The nominal parameters of a pre-fit's estimates (those without an ``EFFECT.`` prefix)."""
    return {k: v for k, v in prefit.estimates.items() if "." not in k}


def set_effects(members: list, candidates: dict, prefit) -> list:
    """The set's effects at their pre-fitted values."""
    return [effect_at_prefit(candidates[k], prefit) for k in members]


def window_items(run) -> list:
    """``[(score, candidate)]`` of every item screened on the window, best first: each effect by its best
    start, and every variant whose options make it other physics (a leak's path) on its own."""
    best: dict = {}
    for score, c, pre in run.window_items:
        if pre is None:
            continue
        key = (c.name, tuple(sorted(c.effect.option_values.items())))
        if key not in best or score > best[key][0]:
            best[key] = (score, c)
    return sorted(best.values(), key=lambda item: -item[0])


def _fit(run, effects: list, start: int, evaluations: int, warm=None, start_values=None):
    """A pre-fit of ``effects`` on the window (``run.stages.window_fit``); None when it fails."""
    try:
        return run.stages.window_fit(run, effects, start, WINDOW_SAMPLES, evaluations, warm=warm,
                                     start_values=start_values)
    except Exception as exc:  # noqa: BLE001 - a set that cannot be integrated is left out
        if not is_solver_failure(exc):
            raise
        return None


def _effect_values(prefit) -> dict:
    """The effect parameters of a pre-fit's estimates (``EFFECT.PARAM``)."""
    return {k: v for k, v in prefit.estimates.items() if "." in k}


def _with(run, window: WindowSet, members: list, candidates: dict, start: int):
    """``members`` (``candidates``) pre-fitted on the window from the data sheet, the set's members at their
    pre-fitted values and a new member at its start (its look-alike start scaling the data sheet's values, as
    alone).  From the data sheet, not from where the set's pre-fit left the nominal parameters: those have bent
    to make up for what the set lacks, and a true effect started there may end above a look-alike."""
    effects = [effect_at_prefit(candidates[k], window.prefit) if k in window.members else candidates[k].effect
               for k in members]
    values = _effect_values(window.prefit)
    for k in members:
        if k not in window.members:
            values.update(data_sheet_start(run.rig, candidates[k]) or {})
    return _fit(run, effects, start, GROW_EVALUATIONS, start_values=values)


def cost(pre) -> float:
    """What a pre-fit on the window minimised: its residuals and its continuity defects weighted as the pre-fit
    weighs them (``docs/decisions/0034``)."""
    return pre.objective(PREFIT_DEFECT_WEIGHT)


def _pays(window: WindowSet, pre, n_added: int) -> tuple[bool, str]:
    """Whether ``pre`` (the set with one more effect) pays on the window, and why (see the module docstring)."""
    n = max(window.prefit.n_residuals, 2)
    before, after = cost(window.prefit), cost(pre)
    gain = n * math.log(before / max(after, 1e-300)) - bic_penalty(n_added, n)
    excess = before - window.prefit.n_residuals
    share = (before - after) / excess if excess > 0 else 0.0
    text = (f"with {', '.join(window.members)} on the window: {window.rms:.3g} -> "
            f"{math.sqrt(after / max(pre.n_residuals, 1)):.3g} times the noise, BIC gain {gain:.0f}, "
            f"{100 * share:.0f} % of what the set leaves above the noise")
    return gain > 0 and share >= GROW_SHARE, text


def _better(a: WindowSet, b: WindowSet) -> WindowSet:
    """The better of two sets grown on the window: of two as large, the lower residual; a larger set wins only
    where it pays against the smaller as a joining effect must (the criterion drops, and it takes at least
    :data:`~.rules.GROW_SHARE` of what the smaller leaves above the noise)."""
    if len(a.members) == len(b.members):
        return a if cost(a.prefit) <= cost(b.prefit) else b
    small, large = (a, b) if len(a.members) < len(b.members) else (b, a)
    gain = small.criterion() - large.criterion()
    excess = cost(small.prefit) - small.prefit.n_residuals
    share = (cost(small.prefit) - cost(large.prefit)) / excess if excess > 0 else 0.0
    return large if gain > 0 and share >= GROW_SHARE else small


def _swap_variants(run, window: WindowSet, items: list, start: int) -> None:
    """Each member tried as each of its other variants (other physics: a leak's path), the rest present."""
    for k in list(window.members):
        for _, c in items:
            if c.name != k or c is window.candidates[k]:
                continue
            trial = dict(window.candidates, **{k: c})
            pre = _fit(run, [effect_at_prefit(trial[m], window.prefit) for m in window.members], start,
                       GROW_EVALUATIONS, start_values=_effect_values(window.prefit))
            if pre is not None and cost(pre) < cost(window.prefit):
                window.log[k] += (f"; as {c.label} with the rest of the set: {cost(pre):.0f} < "
                                  f"{cost(window.prefit):.0f}")
                window.candidates, window.prefit = trial, pre


def _grow_from(run, first, items: list, variants: list, start: int) -> WindowSet | None:
    """The set grown from item ``first`` with the ``items`` of the pool (see the module docstring, 1.-5.), a
    member tried as each of its ``variants``; None when its pre-fit fails."""
    window = WindowSet(members=[first.name], candidates={first.name: first})
    window.prefit = _fit(run, [first.effect], start, GROW_EVALUATIONS,
                         start_values=data_sheet_start(run.rig, first))
    if window.prefit is None:
        return None
    _polish(run, window, start)
    window.log[first.name] = f"starts the set on the window ({window.rms:.3g} times the noise)"
    while len(window.members) < max(1, run.max_findings) and window.rms > GROW_UNTIL:
        tried = {}
        for _, c in items:
            if c.name in window.members or not run.budget.allows(f"the pre-fit of {c.label} with the set", 0.0):
                continue
            pre = _with(run, window, window.members + [c.name], dict(window.candidates, **{c.name: c}), start)
            if pre is not None and (c.name not in tried or cost(pre) < cost(tried[c.name][1])):
                tried[c.name] = (c, pre)
        if not tried:
            break
        best = min(tried, key=lambda k: cost(tried[k][1]))
        c, pre = tried[best]
        ok, text = _pays(window, pre, c.n_added)
        run.say(f"window set {', '.join(window.members)} + {c.label}: {text}: {'joins' if ok else 'stops there'}")
        window.log[best] = text + ("" if ok else ": does not join")
        if not ok:
            break
        window.members.append(best)
        window.candidates[best], window.prefit = c, pre
        _swap_variants(run, window, variants, start)
        _polish(run, window, start)
    return window


def _polish(run, window: WindowSet, start: int) -> None:
    """The set pre-fitted again from the data sheet, its members at their pre-fitted values, as a candidate with
    it is: a candidate's gain is then what it explains, not what the same steps find without it."""
    pre = _fit(run, set_effects(window.members, window.candidates, window.prefit), start, GROW_EVALUATIONS,
               start_values=_effect_values(window.prefit))
    if pre is not None and cost(pre) < cost(window.prefit):
        window.prefit = pre


def grow_on_window(run, ranked: list, variants: dict, start: int) -> WindowSet:
    """The set of effects chosen on the window from sample ``start`` by forward selection of pre-fits (see the
    module docstring); ``ranked`` and ``variants`` are the screening's, ``run.window_items`` its pre-fits.
    Returns the best :class:`WindowSet` (empty when no candidate screened positive)."""
    every = window_items(run)
    items = [(score, c) for score, c in every if score > 0][:max(1, GROW_POOL)]
    if not items:
        return WindowSet()
    # a variant that is other physics (a leak's path) may explain nothing alone and much beside another effect
    pooled = {c.name for _, c in items}
    items += [(score, c) for score, c in every if c.name in pooled and all(c is not d for _, d in items)]
    grown = []
    for _, first in items[:max(1, GROW_STARTS)]:
        window = _grow_from(run, first, items, every, start)
        if window is not None:
            grown.append(window)
            run.say(f"window set from {first.label}: {', '.join(window.members)} at {window.rms:.3g} times the noise")
    if not grown:
        return WindowSet()
    window = grown[0]
    for other in grown[1:]:
        window = _better(window, other)
    for other in grown:
        if other is not window:
            for k in other.members:
                other.log[k] += f" (the set {', '.join(other.members)} lost to {', '.join(window.members)})"
                window.log.setdefault(k, other.log[k])
    if DELAY in window.members:
        _scan_delay(run, window, start)
    return window


def _scan_delay(run, window: WindowSet, start: int) -> None:
    """The set's transport delay scanned by pre-fits of the set on the window; the best replaces it."""
    effects = set_effects(window.members, window.candidates, window.prefit)
    delay, best, scan = scan_on_window(run, effects, window.prefit,
                                       lambda fx: _fit(run, fx, start, GROW_EVALUATIONS,
                                                       start_values=_effect_values(window.prefit)), cost)
    window.log[DELAY] += ("; delay scanned on the window with the set (" + ", ".join(f"{d * 1e3:.4g} ms {c:.0f}"
                                                                                    for d, c in scan) + ")")
    c = window.candidates[DELAY]
    window.candidates[DELAY] = Candidate(DELAY, f"transport delay {delay * 1e3:.4g} ms", make_effect(DELAY, delay_s=delay),
                                         list(c.free), dict(c.start_scale))
    window.prefit = best
