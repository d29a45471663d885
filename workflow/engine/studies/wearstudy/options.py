"""The study's options and result: :class:`WearOptions`, :class:`WearStudy` (what it found, what to change where a
march did not settle)."""
from __future__ import annotations

from dataclasses import dataclass, field

from workflow.engine import penalty


METHODS = ("explicit", "implicit", "pseudo-time")


@dataclass
class WearOptions:
    """``methods`` ⊂ :data:`METHODS`; HB: ``method``, ``nh``, ``nit``,
    ``tol``, ``max_iterations``, ``max_passes``; ``frequency_hz`` (0: first
    tied resonance); Archard ``k_w`` (m²/N) and ``blade_share``; the march:
    ``cycles_per_block``, ``max_blocks``, ``block_tol``, ``steady_tol``,
    ``reference_check``; pseudo-time: ``max_steps``, ``rtol``,
    ``dt_max_blocks``; ``eps_check_factor`` (0: off); ``nh_check``: the
    unworn wear rates re-solved at 1.5×Nh (:func:`nh_check`); ``compare_unworn``:
    also solve the unworn point by Newton and by pseudo-time (the paper's
    comparison); ``operating_point`` "frequency" (``frequency_hz``) or "detuning"
    (``detuning`` × the friction-damped resonance, :mod:`workflow.engine.studies.operating`);
    ``length_m``: the wear law's length scale ℓ [m] (0: node-wise, eq. 21;
    :func:`workflow.engine.wear.law.averaging`) and ``length_over`` how the rate takes it
    ("pressure", "slip" or "all", :class:`workflow.engine.wear.law.Averaging`); ``measure_length_m``: ℓ [m]
    of the filtered profile among the wear measures
    (:mod:`workflow.engine.wear.measures`); ``resonance_shift``: find the friction-damped
    resonance of the worn and the new model (two FRF searches).

    ``operating_point`` "resonance" (the dwell, :func:`_dwell`): ``dwell_tol`` — it ends when a
    stage is steady and the peak of the worn system lies within this fraction of the stage's
    frequency; ``dwell_step`` — the relative move of the peak a stage aims at (its wear budget
    adapts to it); ``dwell_stages`` — stages at most. "mission": ``mission`` ((r, share), …), r =
    f / f_r (f_r the new model's friction-damped resonance), shares of the cycles ≥ 0 summing to 1
    (:func:`workflow.engine.studies.operating.mission_points`). ``control`` "force" (the load as
    built) or "amplitude": the tip held at ``tip_amplitude_m`` [m] (0: the unworn response),
    :mod:`workflow.engine.studies.amplitude`."""

    methods: tuple = ("pseudo-time", "implicit")
    method: str = "hbm"
    nh: int = 3
    nit: int = 64
    tol: float = 1e-8
    max_iterations: int = 100
    max_passes: int = 20
    frequency_hz: float = 0.0
    k_w: float = 1e-13
    blade_share: float = 0.5
    cycles_per_block: float = 1e5
    max_blocks: int = 400
    block_tol: float = 0.01
    steady_tol: float = 1e-4
    reference_check: bool = False
    max_steps: int = 2000
    rtol: float = 1e-3
    dt_max_blocks: float = 0.0
    eps_check_factor: float = penalty.CHECK_FACTOR
    nh_check: bool = True
    compare_unworn: bool = True
    operating_point: str = "frequency"
    detuning: float = 1.0
    measure_length_m: float = 2e-3
    length_m: float = 0.0
    length_over: str = "slip"
    resonance_shift: bool = True
    mission: tuple = ()
    dwell_tol: float = 1e-5
    dwell_step: float = 3e-4
    dwell_stages: int = 100
    control: str = "force"
    tip_amplitude_m: float = 0.0


@dataclass
class WearStudy:
    """What :func:`worn_steady_state` found. ``omega`` (rad/s), ``base`` the
    unworn :class:`SolveResult`, ``histories`` {method: WearHistory},
    ``tracked_pair``; ``unworn`` the Newton/pseudo-time comparison;
    ``profile_max_rel_diff`` and ``cpu_ratio_pseudo_over_reference`` (None
    without both); ``reference_check`` or None; ``eps_check``."""

    omega: float
    hb: object
    rc: object
    base: object
    unworn: dict
    histories: dict
    tracked_pair: int
    profile_max_rel_diff: float | None = None
    cpu_ratio_pseudo_over_reference: float | None = None
    reference_check: dict | None = None
    eps_check: dict = field(default_factory=dict)
    nh_check: dict = field(default_factory=dict)
    operating_point: dict = field(default_factory=dict)
    measures: dict = field(default_factory=dict)
    energy_per_cycle_J: dict = field(default_factory=dict)
    resonance_shift: dict | None = None

    def unconverged(self) -> list[str]:
        """One line per wear method that did not reach the steady state, with what to change:
        the step or block budget — unless the wear rate is not decaying (persistent slip),
        where no budget reaches a worn steady state."""
        def hint(m, h):
            if h.vibration_lost:
                return _lost_hint(h)
            if h.persistent_slip:
                return ("no worn steady state at this load and friction: more steps or blocks "
                        "only wear deeper")
            if h.reason.startswith(DWELL_UNFINISHED):
                return ("raise wear.dwell_stages" if "wear.dwell_stages" in h.reason else
                        "the dwell lost the peak: use wear.operating_point = \"detuning\"")
            return f"raise {'wear.max_blocks' if m in ('explicit', 'implicit') else 'pseudotime.max_steps'}"

        return [f"wear {m}: NOT steady after {h.iterations} iterations ({h.reason}); {hint(m, h)}"
                for m, h in self.histories.items() if not h.steady]

    def warnings(self) -> list[str]:
        """Converged results whose Nh-check exceeds its tolerance or could not be made
        (the ε-check is reported, not tested: :mod:`workflow.engine.studies.epscheck`)."""
        nc = self.nh_check or {}
        ch = nc.get("max_rel_change")
        what = nc.get("measure", "unworn wear rates")
        if nc and ch is None:
            return [f"wear Nh-check: the {what} could not be computed at Nh = {nc['nh']} "
                    f"({nc.get('reason') or 'the solver gave up'}); how converged the wear is in Nh is unknown"]
        if ch is not None and ch > penalty.CHECK_TOL:
            return [f"wear Nh-check: the {what} moves by {ch:.2e} (> {penalty.CHECK_TOL:g}) at "
                    f"Nh = {nc['nh']}, nit = {nc['nit']}; raise hb.harmonics"]
        return []


def _lost_hint(h) -> str:
    """What to change for a march that lost the vibration (``h.vibration_lost``), from its
    re-solve at 1.5×Nh (``h.finer_nh``, :func:`finer_nh_resolve`): more steps or blocks
    cannot help either way."""
    f = h.finer_nh
    if f is None:
        return "more steps or blocks do not help"
    if f["converged"]:
        return (f"at Nh = {f['nh']} (nit = {f['nit']}) the same wear solves in {f['iterations']} iterations: "
                "the vibration was lost to the harmonic truncation — raise hb.harmonics")
    return (f"nor at Nh = {f['nh']} (nit = {f['nit']}) ({f['reason']}): more steps, blocks or harmonics "
            "do not help")


#: How a resonance dwell that spent ``WearOptions.dwell_stages`` says so (:func:`_dwell`).
DWELL_UNFINISHED = "resonance dwell unfinished"
