"""The summary of a run (summary.json): settings, first impact, amplitudes, impacts.

Pure functions of the case and of the history columns; the runner adds the solver's
counters. docs/architecture.md, "Results", lists what summary.json holds.
"""

import numpy as np

from beamcontact.io.case import Case


def effective_settings(case: Case) -> dict:
    """Every [solver] value, defaults included, and for dynamics the step bounds and
    alpha actually used: enough to reproduce the run."""
    settings = case.solver.model_dump()
    an = case.analysis
    if an.kind == "dynamic":
        settings.update(dt=an.dt, dt_min=an.smallest_step, alpha=an.alpha)
    else:
        settings.update(load_steps=an.load_steps)
    return settings


def contact_summary(h: dict, points: list[str], contact) -> dict:
    """First impact, first amplitude of each output point after it, gap extremes.

    The first impact is the first accepted step whose smallest gap is below 1 % of the
    smallest contact radius; the first amplitude of a point is the extreme u_y of its
    first excursion after that time (until u_y changes sign, or the end of the run).
    """
    if contact is None:
        return {}
    gap = h["min_gap"]
    r_min = float(np.min(np.asarray(contact.elements.radius)))
    hit = np.where(gap <= 0.01 * r_min)[0]
    out = {"min_gap": float(np.nanmin(gap)),
           "max_penetration": float(max(0.0, -np.nanmin(gap))),
           "first_impact_time": float(h["t"][hit[0]]) if hit.size else None,
           "first_amplitude": {},
           "impacts": contact_episodes(h)}
    if hit.size:
        for name in points:
            out["first_amplitude"][name] = first_excursion_extreme(h["t"][hit[0]:],
                                                                   h[f"{name}_uy"][hit[0]:])
    return out


def contact_episodes(h: dict, level: float = 1e-4) -> list[dict]:
    """Every contact of the run: it starts at the first step whose contact energy exceeds
    ``level`` times the largest E_kin + E_strain + |E_contact| of the run, and ends at the
    first step after it where it falls below a quarter of that (the hysteresis keeps a
    grazing contact from counting as many). For each: start and end time (None if still
    in contact at the end), the smallest gap, and the changes of the total energy, of
    E_dissipated and of E_set_change from the step before it starts to the step where it
    ends (E_change = E_set_change - E_dissipated)."""
    e_con, t = np.abs(h["E_contact"]), h["t"]
    threshold = level * float(np.max(h["E_kin"] + h["E_strain"] + e_con))
    episodes, k, n = [], 0, len(t)
    while k < n:
        if not e_con[k] > threshold:
            k += 1
            continue
        begin = k
        while k < n and not e_con[k] < 0.25 * threshold:
            k += 1
        before, after = max(begin - 1, 0), min(k, n - 1)
        episodes.append({
            "start": float(t[begin]), "end": float(t[k]) if k < n else None,
            "min_gap": float(np.min(h["min_gap"][begin:after + 1])),
            "E_total_before": float(h["E_total"][before]),
            "E_change": float(h["E_total"][after] - h["E_total"][before]),
            "E_dissipated": float(h["E_dissipated"][after] - h["E_dissipated"][before]),
            "E_set_change": float(h["E_set_change"][after] - h["E_set_change"][before])})
    return episodes


def first_excursion_extreme(t: np.ndarray, uy: np.ndarray, level: float = 0.01) -> dict:
    """Extreme of the first excursion of ``uy``: it starts where |uy| first exceeds
    ``level`` times max |uy| and ends where uy passes that level with the opposite sign
    (or at the end), so that round-off wiggles about zero do not count as excursions.
    ``ended`` is False when the excursion has not ended by the last step: the value is
    then the extreme so far, and the run too short to give the amplitude."""
    tau = level * float(np.max(np.abs(uy)))
    if tau == 0.0:
        return {"uy": 0.0, "t": float(t[0]), "ended": False}
    k0 = int(np.argmax(np.abs(uy) > tau))
    sign = np.sign(uy[k0])
    back = np.where(sign * uy[k0:] < -tau)[0]
    end = k0 + (int(back[0]) if back.size else len(uy) - k0)
    k = k0 + int(np.argmax(sign * uy[k0:end]))
    return {"uy": float(uy[k]), "t": float(t[k]), "ended": bool(back.size)}


def unfinished_amplitude_warning(first_amplitude: dict) -> str | None:
    """A warning naming the output points whose first excursion after the first impact
    has not ended by t_end (their first_amplitude is the extreme so far), else None."""
    open_ = [name for name, a in first_amplitude.items() if not a.get("ended", True)]
    if not open_:
        return None
    return (f"first_amplitude of {', '.join(open_)}: the first excursion after the first "
            f"impact has not ended by t_end, so the value is the extreme so far (a longer "
            f"analysis.t_end gives the amplitude)")


def shared_cores_warning(loop_threads: dict | None, most: int, share: float = 0.1,
                         probe_s: float = 0.0) -> str | None:
    """A warning when the native engine's compiled time loop ran more than ``share`` of
    its time on fewer threads than the ``most`` its process may use (``loop_threads``:
    seconds per thread count, summary.json): other processes kept cores busy, so the run
    took longer than on an idle machine; its numbers are the same (docs/engines.md,
    "Threads"). ``probe_s``: the seconds on one thread before the first reading of the
    cores (summary.json ``loop_probe_s``), not counted as shared. None otherwise, and for
    the JAX engine (``loop_threads`` None)."""
    if not loop_threads:
        return None
    total = sum(loop_threads.values())
    fewer = max(sum(seconds for count, seconds in loop_threads.items() if int(count) < most)
                - probe_s, 0.0)
    if total <= 0.0 or fewer <= share * total:
        return None
    return (f"the step loop ran {fewer:.2f} of its {total:.2f} s on fewer threads than the "
            f"{most} this process may use: other processes kept cores busy, so it took "
            f"longer than on an idle machine (the results do not depend on it; "
            f"summary.json loop_threads)")


def _energy_scale(energy: dict) -> float:
    """The scale the energy warnings compare with: the larger of the initial total and the
    largest kinetic energy of the run."""
    return max(abs(energy["E_total_initial"]), energy.get("E_kin_max", 0.0))


def integration_energy_warning(energy: dict | None, fixed_steps: bool,
                               limit: float = 0.05) -> str | None:
    """A warning when the time integration added more than ``limit`` of the energy scale
    (the larger of the initial total and the largest kinetic energy) at some point of the
    run (``E_dissipated_min``, the least cumulative E_dissipated), else None.

    A conservative system's integrator adds energy when its steps cross a stiff part of a
    contact potential without resolving it (docs/theory.md, "Energy account"): at fixed
    steps (``solver.error_tol = 0``) an impact can add a large part of E_total, which no
    conclusion drawn from the run should rest on.
    """
    if not energy or "E_dissipated_min" not in energy:
        return None
    scale = _energy_scale(energy)
    added = -energy["E_dissipated_min"]
    if scale <= 0.0 or added <= limit * scale:
        return None
    advice = ("solver.error_tol = 0 keeps the steps fixed, so the impacts are not resolved; "
              "the default error control resolves them" if fixed_steps
              else "a smaller solver.error_tol or energy_tol resolves the impacts better")
    return (f"the time integration added up to {added:.4g} J ({100 * added / scale:.2g} % of "
            f"{scale:.4g} J; the least E_dissipated in history.csv): {advice}")


def set_change_warning(energy: dict | None, pairing: str, limit: float = 0.01) -> str | None:
    """A warning when IPIP's set changes moved the energy by more than ``limit`` of its
    scale (the larger of the initial total and the largest kinetic energy), else None.

    With the paper's "zones" rule a contact zone that appears while the beams overlap
    starts with energy (docs/theory.md, "IPIP pairing rules"); the account reports it,
    and the warning says what to do about it.
    """
    if not energy or "E_set_change" not in energy:
        return None
    scale = _energy_scale(energy)
    jump = energy["E_set_change"]
    if scale <= 0.0 or abs(jump) <= limit * scale:
        return None
    advice = ('contact.pairing = "points" makes the contact energy continuous'
              if pairing == "zones" else "a shorter error_tol or energy_tol reduces it")
    return (f"IPIP contact-set changes changed the energy by {jump:+.4g} J "
            f"({100 * jump / scale:+.2g} % of {scale:.4g} J; E_set_change in history.csv); "
            f"{advice}")
