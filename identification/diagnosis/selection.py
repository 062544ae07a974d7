"""Forward selection: add the best candidate, refit the full nonlinear model, rediagnose — until the
verdict is ``noise`` or the held-out check stops it (``kinid identify --auto``)."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from kinid.checks import check_positive
from kinid.progress import as_progress, step
from kinid.threads import blas_single_threaded

from ..model import Machine, check_effects, check_machine, chosen_of, implausible_effects
from ..data import Observations, check_observations
from ..fitting import FitResult
from .diagnose import ALPHA, Diagnosis, diagnose, passed_over

__all__ = ["SelectionStep", "forward_select", "what_is_left"]


#: A warm-started refit taking more iterations than this is redone from a cold start.
WARM_START_ITERATIONS = 15


def _set_aside(machine, obs, effects, noise_um, progress, before: tuple, first=None):
    """``obs`` without its gross errors, the tuple of all set aside so far (rows of the original data), and the fit of
    ``effects`` on the rows kept (None if not made); ``first``: a Diagnosis of ``effects`` on ``obs`` to start from
    (its fit and leverages)."""
    from ..fitting import set_aside_with_fit

    kept, new, result = set_aside_with_fit(machine, obs, effects, noise_um=noise_um,
                                           first=None if first is None else first.fit,
                                           first_hat=None if first is None else first.hat)
    if not new:
        return obs, before, result
    if before:  # rows of ``obs`` -> rows of the data as read: keep the first record's numbering
        rows = [i for i in range(len(obs) + len(before)) if i not in {a.row for a in before}]
        new = tuple(replace(a, row=rows[a.row]) for a in new)
    for a in new:
        progress.say(f"  set aside as a gross error: {a.describe()}")
    return kept, before + new, result


@dataclass(frozen=True)
class SelectionStep:
    """One step of forward selection: the model, its fit and its diagnosis, and what was added to reach it.

    ``stopped`` is empty but on the last step, where it says in words why the
    selection ended there. ``data`` are the alignments the step used (gross
    errors set aside). ``held_out`` is the held-out check of the best candidate
    against this step's model (:class:`~kinid.identification.fitting.crossval.CrossValidation`),
    if it was run: the next step's effect passed it, the last step's failed it.
    ``undetermined`` (last step): the error joints whose periodic error was added at
    a period the positions measured do not determine; the model is then not
    determined between those positions, and the last step's verdict is
    ``missing-effect`` even where its residual is noise. ``instrument`` (last step): the instrument's errors
    (``camera-scale``, ``camera-rotation``, ``laser-scale``) the residual follows more than any machine error
    explains it, when the selection stopped for them (rows with offsets only); the verdict is then
    ``missing-effect``, its note naming them.
    """

    added: str | None
    fit: FitResult
    diagnosis: Diagnosis
    stopped: str = ""
    data: Observations | None = None
    held_out: object = None
    undetermined: tuple = ()
    instrument: tuple = ()


@blas_single_threaded
def forward_select(machine: Machine, obs: Observations, effects, *, noise_um=None, alpha: float = ALPHA,
                   max_steps: int = 8, progress=None, robust: bool = True, folds: int = 4) -> list:
    """Add the best candidate, refit the full nonlinear model, rescore; until the verdict is ``noise``.

    Parameters
    ----------
    progress : Progress, text stream or None
        Where to say one line per step (the RMS falling against σ); see :func:`kinid.progress.as_progress`.
    robust : bool
        Set gross errors aside (:func:`~kinid.identification.fitting.outliers.set_aside_outliers`)
        with the starting model and again with the final one. Misreads that stand out only once the
        model is complete (the residual of a missing effect hid them) may have steered what was added:
        the selection is then run once more from the starting model without them.
    folds : int
        An effect is added only if it also lowers the held-out RMS of this many
        blocks of the data (:func:`~kinid.identification.fitting.crossval.cross_validate`); 0 skips the check.

    Returns
    -------
    list of SelectionStep
        The first step is the starting model.
    """
    check_machine(machine)
    check_observations(obs)
    effects = list(check_effects(machine, effects))
    progress = as_progress(progress)
    if noise_um is not None:
        noise_um = check_positive("noise_um", noise_um)
    aside, start = (), None
    if robust:
        obs, aside, start = _set_aside(machine, obs, effects, noise_um, progress, aside)
    settings = dict(noise_um=noise_um, alpha=alpha, max_steps=max_steps, progress=progress, robust=robust, folds=folds)
    steps = _select(machine, obs, list(effects), aside, start=start, **settings)
    last = steps[-1]
    if robust and len(steps) > 1 and len(last.fit.set_aside) > len(aside):
        progress.say(f"  {len(last.fit.set_aside) - len(aside)} gross errors stood out only at the end; "
                     f"the selection runs again without them")
        steps = _select(machine, last.data, list(effects), last.fit.set_aside, **settings)
    progress.say(f"  {what_is_left(steps)}")
    return steps


def what_is_left(steps) -> str:
    """For the final model of a selection: what share of the starting model's residual it explains, whether
    anything structured remains (a significant candidate, the neighbour test, the residual against σ), where
    the model holds an error at each of an axis's few positions, that it is not measured between them, and where it
    holds a step, the two readings it lies between."""
    return _explained(steps) + _between_positions(steps[-1])


def _between_positions(step) -> str:
    """What the final model's errors along an axis read at few positions do not know, in words: a table (the error
    at each of a linear axis's few positions), and any other error varying with the position of an axis, linear or
    rotary, read at no more positions than a table is made for (an A axis read at 7 angles)."""
    from ..model import TABLE_POSITIONS, basis_of, position_tables
    from ..data import positions_per_axis

    if step.data is None:
        return ""
    machine = step.fit.machine
    positions = positions_per_axis(machine, step.data)
    names = set(position_tables(machine, positions))
    tables = [e for e in step.fit.effects if e.name in names]
    steps = [e for e in step.fit.effects if chosen_of(e.name) == "step position"]
    few = [e for e in step.fit.effects if e.name not in names and e.axis in positions and basis_of(e).positional
           and 1 < positions[e.axis] <= max(TABLE_POSITIONS) and e not in steps]
    text = "".join(_step_place(machine, step.data, e) for e in steps)
    if tables:
        axes = sorted({e.axis for e in tables})
        where = " and ".join(f"the {positions[a]} positions of {a}" for a in axes)
        which = " and ".join(e.name for e in tables)
        text = (f"; {which} {'is' if len(tables) == 1 else 'are'} the error at each of {where} measured (too few "
                f"for a map): between them a polynomial through those values, not a measurement — measure "
                f"{' and '.join(axes)} at more positions to know it there")
    for axis in sorted({e.axis for e in few}):
        which = " and ".join(e.name for e in few if e.axis == axis)
        where = "angles" if machine.axis(axis).kind != "prismatic" else "positions"
        text += (f"; {which} {'varies' if ' and ' not in which else 'vary'} with {axis}, read at {positions[axis]} "
                 f"{where}: between the {positions[axis]} {where} of {axis} the model is interpolation, not a "
                 f"measurement — measure {axis} at more {where} to know it there")
    return text


def _step_place(machine, data, e) -> str:
    """Where the data place the step ``e``, in words: between the two readings of its axis either side of it."""
    from .steps import step_interval

    low, high = step_interval(machine, data, e.name)
    unit = " mm" if machine.axis(e.axis).kind == "prismatic" else "°"
    if low is None or high is None:
        return f"; {e.name} has readings of {e.axis} on one side only: it is not measured"
    return (f"; {e.name} jumps between the readings {e.axis} = {low:.6g} and {high:.6g}{unit}, where in between is not "
            f"measured (the name's {e.args[0]:g} is a point of that interval) — measure {e.axis} between them to place "
            f"it")


def _explained(steps) -> str:
    first, final = steps[0].diagnosis, steps[-1].diagnosis
    ss0, ss1 = first.rms_um ** 2, final.rms_um ** 2
    share = f"{1.0 - ss1 / ss0:.0%}" if ss0 > 0 else "all"
    text = (f"the final model explains {share} of the starting model's residual sum of squares (RMS "
            f"{first.rms_um:#.3g} → {final.rms_um:#.3g} µm per coordinate, σ {final.noise_um:#.3g} µm)"
            if len(steps) > 1 else
            f"no effect was added (RMS {final.rms_um:#.3g} µm per coordinate, σ {final.noise_um:#.3g} µm)")
    best, passed = final.advised
    st = final.structure
    also = f"; {final.note}" if steps[-1].undetermined and final.note else ""  # a period added but not determined
    if best is not None and best.p_value < final.threshold:
        return text + (f"; structure remains: {best.effect} is significant (p = {best.p_value:.2g}) but was not "
                       f"added ({_why_not_added(steps[-1])})") + also
    if passed and passed[0][0].p_value < final.threshold:
        c, odd = passed[0]
        return text + (f"; structure remains: {c.effect} is significant (p = {c.p_value:.2g}) but was not added (it "
                       f"would need {odd.describe()})") + also
    if final.verdict == "missing-effect":
        return text + f"; structure remains: {final.note}" if final.note else text + "; structure remains"
    if st is not None:
        sigma_note = f"; {final.note}" if final.verdict == "noise" and final.note else ""  # a σ given too small
        return text + (f"; nothing structured remains: no candidate is significant and neighbouring alignments "
                       f"agree no more than noise would (p = {st.p_value:.2g})") + sigma_note
    return text + "; nothing structured remains: no candidate is significant"


def _why_not_added(last) -> str:
    """Why the last step's significant candidate stayed out, in a few words (its stop message says it in full)."""
    from ..fitting import MIN_GAIN_SE

    cv = last.held_out
    if cv is None and last.diagnosis.inseparable:  # time follows an axis: the plan cannot tell the two apart
        return last.diagnosis.inseparable.split(" (--auto adds neither)")[0]
    if cv is not None and not cv.improves:
        if cv.gain_se >= MIN_GAIN_SE and cv.chosen_gain_se is not None:
            bar = cv.chosen_min_gain_se
            return (f"chosen on part of the alignments, its {cv.what_chosen} does not predict the others better: a "
                    f"gain of {cv.chosen_gain_se:.1f} standard errors" + (f", {bar:g} needed" if bar > 0 else ""))
        return (f"it does not predict held-out alignments better: a gain of {cv.gain_se:.1f} standard errors, "
                f"{MIN_GAIN_SE:g} needed")
    return last.stopped.split("; ")[0]


def _select(machine, obs, effects, aside, *, noise_um, alpha, max_steps, progress, robust, folds, start=None) -> list:
    """The selection loop of :func:`forward_select` from ``effects`` on ``obs`` (``aside``: set aside so far;
    ``start``: the fit of ``effects`` on ``obs`` from a cold start, when the set-aside made it)."""
    from .searched import refined_time_constant

    added = None
    steps = []
    theta0 = None
    carried = None
    undetermined = {}  # error joint -> why the period added for it is not determined by the data
    for k in range(max_steps + 1):
        with step(f"  fitting {'the model' if added is None else added} and scoring the candidates (step {k + 1})"):
            dg = diagnose(machine, obs, effects, noise_um=noise_um, carried_noise=carried, alpha=alpha,
                          theta0=theta0, result=start if theta0 is None else None)  # the first fit: the set-aside's
        if theta0 is not None and (not dg.fit.success or dg.fit.iterations > WARM_START_ITERATIONS):
            # the warm start stalled: a cold start reaches the optimum the model has
            cold = diagnose(machine, obs, effects, noise_um=noise_um, carried_noise=carried, alpha=alpha)
            if cold.rms_um <= dg.rms_um:
                dg = cold
        dg = replace(dg, fit=replace(dg.fit, set_aside=aside))
        odd = () if added is None else implausible_effects(dg.fit, names=(added,))
        if odd:  # the candidate explains the data only with a size no machine has: not added
            effects.pop()
            stop = f"adding {added} needs {odd[0].describe()}: {odd[0].remedy}; not added"
            steps[-1] = replace(steps[-1], stopped=stop)
            progress.say(f"  stopped: {stop}")
            break
        steps.append(SelectionStep(added, dg.fit, dg, data=obs))
        what = "start" if added is None else f"+ {added}"
        progress.say(f"  {what:<28} RMS {dg.rms_um:8.3f} µm   σ {dg.noise_um:.3f} µm   {dg.verdict}")
        best, passed, pending = _first_determined(dg)
        instrument = _instrument_first(machine, obs, dg, best)
        # time follows an axis and the best candidate explains the data no better than one of the other kind: the
        # plan cannot tell which it is, and a model of either would compensate the wrong cause
        inseparable = bool(dg.inseparable) and best is not None and best.effect == dg.advised[0].effect
        stop = ""
        name = None  # the effect added: the best candidate, a warm-up at its refined time constant
        plausible_next = best is not None and best.p_value < dg.threshold
        if passed and plausible_next and dg.verdict != "noise":
            progress.say(f"  {'':<28} passed over: " + "; ".join(passed_over(*p) for p in passed[:3]))
        if instrument is not None:
            against = f", the best candidate {best.effect}'s {best.statistic:.1f}" if best is not None else ""
            stop = (f"the residual follows the offsets read more than any machine error explains it (χ² drop "
                    f"{instrument.statistic:.1f}{against}): "
                    f"{instrument.describe()}; an error of the instrument is not added as a machine error — "
                    f"calibrate the instrument (or correct the offsets) and measure again")
        elif dg.verdict == "noise":
            stop = dg.note or f"the residual is explained by noise of σ = {dg.noise}"
        elif passed and not plausible_next and passed[0][0].p_value < dg.threshold:  # only sizes no machine has
            stop = f"the best candidate, {passed_over(*passed[0])}: {passed[0][1].remedy}; not added"
        elif best is None:
            stop = ("the data ask for more than the model holds, but no candidate of the library can be separated "
                    "from the model: see the aliased candidates")
        elif best.p_value >= dg.threshold:
            stop = (f"no candidate is significant: the best, {best.effect}, has p = {best.p_value:.2g} above the "
                    f"threshold {dg.threshold:.2g}" + (f"; {dg.note}" if dg.note else ""))
        elif inseparable:
            stop = f"the best candidate, {best.effect} (p = {best.p_value:.2g}), is not added: {dg.inseparable}"
        elif len(steps) > max_steps:
            stop = f"stopped after {max_steps} added effects (max_steps); the best next candidate is {best.effect}"
        elif folds:
            from ..fitting import cross_validate
            from ..model import parse_effect as _parse

            name = refined_time_constant(machine, obs, dg.fit, best.effect, dg.noise_um)  # tested as it would be added
            refined = f" (time constant refined: {name.split(':')[2]})" if name != best.effect else ""
            cv = cross_validate(machine, obs, effects, _parse(name, machine), folds=folds, noise_um=noise_um,
                                theta0=dg.fit.theta, choose=_chosen_again(machine, obs, name, dg.fit, best.effect,
                                                                          dg.noise_um))
            progress.say(f"  {'':<28} next: {best.effect}{refined}, p = {best.p_value:.2g}, {cv}")
            steps[-1] = replace(steps[-1], held_out=cv)
            if not cv.improves:
                stop = (f"the best candidate, {best.effect} (p = {best.p_value:.2g}), does not predict held-out "
                        f"data better: {cv}")
        also = list(undetermined.values()) + ([dg.undetermined] if stop and pending else [])
        if stop and also:
            stop += "; also: " + "; ".join(also)
        if stop:
            if robust:  # a misread may stand out only once the model is complete
                # the step's fit is the first round's: the model and rows are those the set-aside fits
                kept, more, _ = _set_aside(machine, obs, effects, noise_um, progress, aside, first=dg)
                if more != aside:
                    obs, aside = kept, more
                    dg = diagnose(machine, obs, effects, noise_um=noise_um, carried_noise=carried, alpha=alpha,
                                  theta0=dg.fit.theta)
                    dg = replace(dg, fit=replace(dg.fit, set_aside=aside))
            periods = tuple(code for code in undetermined
                            if any(e.name.startswith(code + ":periodic:") for e in effects))
            if periods and (dg.verdict == "noise" or not dg.note):  # said unless the verdict says something else
                dg = replace(dg, verdict="missing-effect", note=(
                    f"the period of the periodic error added for {' and '.join(periods)} is not determined by the "
                    f"positions measured: the model is not determined between them (measure "
                    f"{' and '.join(sorted({machine.error_joint(c).axis for c in periods}))} at more positions)"))
            named = instrument.named if instrument is not None and stop.startswith("the residual follows") else ()
            if named:
                dg = replace(dg, verdict="missing-effect", note=(
                    f"the residual follows the offsets read: {instrument.describe()} (an error of the instrument, "
                    f"not of the machine: calibrate it and measure again)"))
            steps[-1] = replace(steps[-1], fit=dg.fit, diagnosis=dg, stopped=stop, data=obs, undetermined=periods,
                                instrument=named)
            progress.say(f"  stopped: {stop}")
            break
        from ..model import parse_effect

        if pending:  # the period is not determined: said when the selection stops
            code, why = pending
            undetermined[code] = why
        if name is None:
            name = refined_time_constant(machine, obs, dg.fit, best.effect, dg.noise_um)
            if name != best.effect:
                progress.say(f"  {'':<28} time constant refined: {best.effect} → {name}")
        effects.append(parse_effect(name, machine))
        theta0 = np.r_[dg.fit.theta, np.zeros(effects[-1].n_params)]
        added = name
        carried = dg.noise if dg.noise.known else None
    return steps


def _instrument_first(machine, obs, dg, best):
    """The instrument's errors when they are significant themselves (:func:`~.instrument.instrument_errors`) and
    explain the residual at least as well as the best significant candidate, or no candidate is significant (a
    laser's scale on an arm: the fit takes part of it into the joints' errors, no machine candidate stands out, and
    the verdict said noise while the laser's scale dropped the χ² by thousands); None otherwise, and for
    alignments."""
    if obs.offsets_mm is None:
        return None
    from .instrument import instrument_errors

    found = instrument_errors(machine, obs, dg.fit, dg.noise_um)
    if found is None or not found.named or found.p_value >= dg.threshold:
        return None
    if best is not None and best.p_value < dg.threshold and found.statistic < best.statistic:
        return None
    return found


def _chosen_again(machine, obs, name: str, result, start: str | None = None, sigma: float = 1.0):
    """For the held-out check: what the data chose among many, chosen again on each turn's training blocks
    (:data:`CHOOSERS`, by the kind of the candidate ``name``; None for a kind the data do not choose): a function
    (training data, the turn's fit of the model, their rows of the error-joint Jacobian at ``result`` or None) →
    the turn's candidate. ``result``: the fit of the model on all of ``obs``; ``start``: the
    candidate the diagnosis proposed, where ``name`` is it refined (a warm-up's time constant); ``sigma`` the
    noise σ, µm."""
    make = CHOOSERS.get(chosen_of(name))
    return None if make is None else make(machine, obs, name, result, start or name, sigma)


def _period_again(machine, obs, name, result, start, sigma):
    """A periodic candidate's period, by the period search over the periods the positions of all of ``obs`` resolve
    (:func:`~kinid.identification.diagnosis.searched.period_found_on`); the candidate itself where the turn finds its period
    again, within what the turn's data determine (its fit serves)."""
    from kinid.errors import DataError

    from ..model import parse_effect
    from .searched import period_found_on

    code, period = name.split(":")[0], float(name.split(":")[2])

    def choose(train, turn, d_errors):
        found = period_found_on(machine, train, turn, code, range_of=obs, d_errors=d_errors)
        if found is None or abs(found.period - period) <= found.period_std:
            return parse_effect(name, machine)
        try:
            return parse_effect(found.effect, machine)
        except DataError:
            return parse_effect(name, machine)
    return choose


def _window_again(machine, obs, name, result, start, sigma):
    """A local error's window, among the windows the diagnosis tries on its joint and around the candidate that the
    turn's rows hold up (:func:`~kinid.identification.diagnosis.local_errors.window_found_on`)."""
    from ..model import parse_effect
    from .local_errors import local_windows, window_found_on

    candidate = parse_effect(name, machine)
    windows = [w for w in local_windows(machine, obs, name.split(":")[0], near=candidate)
               if w.name != name] + [candidate]
    return lambda train, turn, d_errors: window_found_on(machine, train, turn, windows, d_errors) or candidate


def _time_constant_again(machine, obs, name, result, start, sigma):
    """A warm-up's time constant, refined from ``start``'s as the selection refines it
    (:func:`~kinid.identification.diagnosis.searched.refined_time_constant`)."""
    from ..model import parse_effect
    from .searched import refined_time_constant

    if obs.t_s is None:
        return None
    return lambda train, turn, d_errors: parse_effect(
        refined_time_constant(machine, train, turn, start, sigma, d_errors=d_errors), machine)


def _step_again(machine, obs, name, result, start, sigma):
    """A step's position, searched again between the turn's readings of its axis
    (:func:`~kinid.identification.diagnosis.steps.step_found_on`); the candidate itself where the turn places it in
    the same interval."""
    from ..model import parse_effect
    from .steps import step_found_on

    return lambda train, turn, d_errors: parse_effect(step_found_on(machine, train, turn, name, d_errors), machine)


#: How the held-out check's turns choose again what the data chose, by the kind of candidate (the choice's name
#: and the gain it must bring: :data:`~kinid.identification.fitting.crossval.CHOSEN_AGAIN`).
CHOOSERS = {"period": _period_again, "window": _window_again, "time constant": _time_constant_again,
            "step position": _step_again}


def _first_determined(dg):
    """The best live candidate a machine could have (``dg.advised``), the better ones passed over, and
    (error joint, why) when the diagnosis found it periodic with a period the
    positions measured do not determine (:mod:`.ambiguity`), else None. Such a candidate is named by the longest of
    the periods that fit as well — it reproduces every position measured as well as any of them, and between them
    it is the smoothest (the convention of the period search: of aliases, the lowest frequency) — and on a rotary
    axis by the longest of those that make a whole number of cycles per turn, if any does: a gear has whole teeth,
    and such a model does not jump where a table's readings come round (191.9° fits six table angles as well as
    180°)."""
    best, passed = dg.advised
    if best is None or not dg.undetermined:
        return best, passed, None
    code, _, period = best.effect.split(":")[:3]
    periods, which = (float(period),) + tuple(dg.twins), "the longest of them"
    machine = dg.fit.machine
    if machine.axis(machine.error_joint(code).axis).kind != "prismatic":
        whole = [p for p in periods if round(360.0 / p) >= 1 and f"{360.0 / round(360.0 / p):.6g}" == f"{p:.6g}"]
        periods, which = (whole, "the longest of them with whole cycles per turn") if whole else (periods, which)
    longest = max(periods)
    name = best.effect if longest == float(period) else f"{code}:periodic:{longest:.6g}"
    why = dg.undetermined.replace(" — measure", f"; {name} added, {which} — measure")
    return replace(best, effect=name), passed, (code, why)
