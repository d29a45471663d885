"""Scene sections: one dataclass per TOML table, every key with unit and doc.

Light on purpose (no numerical imports) so that reading and validating a scene
costs nothing. The geometry section is ``geometry.params.SectorParams``. Each
owner keeps its section here; cross-key rules go in a ``check`` method that
raises :class:`~workflow.errors.SceneError` naming the keys.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from workflow.errors import SceneError
from workflow.schema import param, shown

PRODUCTS = ("mesh", "bundle", "modes", "reduced", "reduction_check", "frf", "wear", "wear_map", "extreme", "report",
            "scaling", "verification", "contact_convergence", "interface_scaling", "cyclic_modes",
            "nonlinear_modes", "mistuning")


@dataclass
class Run:
    outputs: list = param(["modes"], "", "products this scene asks for; the stages they need run, no others",
                          item_choices=PRODUCTS)
    title: str = param("", "", "title shown in the report")


@dataclass
class Model:
    bundle: str = param("", "path", "an existing model bundle folder to use instead of geometry + assembly "
                                    "(relative paths are relative to the scene file)")


@dataclass
class Material:
    young: float = param(110e9, "Pa", "Young's modulus (Ti-6Al-4V); an engineering solid's range, in which the "
                                      "eigensolvers' scaling holds", min=1e3, max=1e13)
    poisson: float = param(0.33, "", "Poisson's ratio", min=-0.99, max=0.499)
    density: float = param(4430.0, "kg/m³", "mass density; an engineering solid's range, in which the "
                                            "eigensolvers' scaling holds", min=1.0, max=1e5)


@dataclass
class Rotation:
    speed_rpm: float = param(0.0, "rpm", "rotation speed Ω about the engine (x) axis: centrifugal load, stress "
                                         "stiffening, spin softening", min=0.0, max=1e5)
    stress_stiffening: bool = param(True, "", "add K_σ from the static prestress (interface tied)")
    spin_softening: bool = param(True, "", "subtract Ω² M_⊥")
    prestress_iterations: int = param(0, "", "re-solve the static prestress with its own K_σ this many times "
                                             "(stress-stiffened static state; 0 = linear prestress)", min=0)

    def check(self):
        if self.speed_rpm > 0 and self.spin_softening and not self.stress_stiffening:
            # Measured on the quick sector: the blade, held only at its flanks, gets a rigid motion of
            # stiffness −6.2e4 N/m (lowest eigenvalue of the condensed static stiffness) against −8.9e2 N/m
            # with both terms and 0 with neither, and the static contact state has no equilibrium.
            raise SceneError("rotation.spin_softening = true with rotation.stress_stiffening = false: both come "
                             "from the centrifugal field, and spin softening alone makes the blade's rigid "
                             "motions in its slot unstable (no static contact state); set both (the default) "
                             "or neither")


@dataclass
class Damping:
    alpha: float = param(0.0, "1/s", "Rayleigh mass coefficient: C = αM + βK", min=0.0)
    beta: float = param(0.0, "s", "Rayleigh stiffness coefficient", min=0.0)
    modal_ratio: float = param(0.002, "", "if > 0, β is chosen so the first tied mode has this damping ratio "
                                          "(added to beta)", min=0.0, max=1.0)


@dataclass
class Excitation:
    amplitude: float = param(0.1, "N", "amplitude of the harmonic force at the blade tip (paper: 0.1 N)", min=0.0,
                             min_exclusive=True)
    static_force: float = param(0.0, "N", "extra static radial (+z) force on the blade tip, for Ω = 0 studies")


@dataclass
class Modes:
    count: int = param(10, "", "eigenfrequencies of the full tied model to compute", min=1)


@dataclass
class Reduction:
    modes: int = param(80, "", "fixed-interface modes kept (0: use cutoff_hz); 80 keeps the first 10 tied "
                               "frequencies of the default sector within 1e-4 and MAC > 0.99999", min=0)
    cutoff_hz: float = param(0.0, "Hz", "keep fixed-interface modes below this frequency (0: use modes)", min=0.0)
    check_modes: int = param(10, "", "eigenfrequencies compared reduced vs full", min=1)
    check_mode_counts: list = param([10, 20, 40, 80], "", "fixed-interface mode counts for the convergence study",
                                    min=0)
    frf_points: int = param(40, "", "frequencies of the linear FRF comparison", min=2)
    cyclic_harmonics: int = param(6, "", "cyclic sector (geometry.cyclic): the reduction prepares the nodal "
                                         "diameters (j·EO) mod N of harmonics j = 0 … this (one Craig–Bampton "
                                         "per ND); hb/wear harmonics beyond need it raised", min=1)

    def check(self):
        if self.modes == 0 and self.cutoff_hz == 0:
            raise SceneError("reduction.modes = 0 needs reduction.cutoff_hz > 0 (keep the fixed-interface modes "
                             "below it), or set reduction.modes > 0")


@dataclass
class Contact:
    mu: float = param(0.5, "", "Coulomb friction coefficient (paper: 0.5, titanium on titanium)", min=0.0)
    eps_n: float = param(0.0, "N/m", "DLFT normal penalty ε_N (0: automatic, from the reduced stiffness)", min=0.0)
    eps_t: float = param(0.0, "N/m", "DLFT tangential penalty ε_T (0: automatic)", min=0.0)
    penalty_factor: float = param(0.0, "", "0: automatic penalties, the stiffness the contact DOFs show the "
                                           "unresolved harmonics (≈ the static condensed stiffness on the dovetail, "
                                           "up to 1e3× it on inertia-dominated contacts; workflow/engine/penalty.py); "
                                           "> 0: this many times each pair's static condensed stiffness",
                                  min=0.0, max=1e6)
    eps_check: float = param(10.0, "", "re-solve each result's peak (march the wear again) with ε multiplied by "
                                       "this and report the "
                                       "change (0: off)", min=0.0)
    gap: float = param(0.0, "m", "initial normal gap added to every pair (<0: interference)")
    max_passes: int = param(20, "", "DLFT periodic passes at most (stick reference convergence)", min=1)
    stiffness_n: float = param(0.0, "N/m³", "normal contact stiffness per unit area: an elastic interface layer "
                                            "k_n·A in series with each pair (reduction/layer.py); 0: rigid, the "
                                            "paper's contact", min=0.0)
    stiffness_t: float = param(0.0, "N/m³", "tangential contact stiffness per unit area (k_t·A in series with "
                                            "each pair's Coulomb slider); 0: rigid", min=0.0)

    @property
    def layered(self) -> bool:
        """True where the scene gives the contact an elastic interface layer."""
        return self.stiffness_n > 0 or self.stiffness_t > 0


@dataclass
class HB:
    methods: list = param(["hbm"], "", "formulations: hbm (AFT), tcm (collocation), hdhb (time samples)",
                          item_choices=("hbm", "tcm", "hdhb"))
    harmonics: list = param([3], "", "numbers of harmonics Nh (≥ 1: harmonic 1 is the response)", min=1, max=256)
    time_samples: list = param([0], "", "nit per period; 0: the smallest power of 2 ≥ 4(2Nh+1), at least 64 (HDHB always uses 2Nh+1)", min=0,
                               max=16384)
    solver: str = param("newton", "", "nonlinear solver, first of the cascade (workflow/engine/cascade.py); "
                                      "newton-powell: ≤30 Newton steps along the ε-path, hybrid Powell from the "
                                      "best iterate, then pseudo-transient continuation from the best guess",
                        choices=("newton", "powell", "newton-powell", "pseudo-time"))
    tol: float = param(1e-8, "", "residual tolerance relative to ‖F_r‖", min=0.0, min_exclusive=True)
    max_iterations: int = param(100, "", "solver iterations at most", min=1)
    reference_harmonics: int = param(0, "", "Nh of the converged reference for the error table (0: off)", min=0, max=256)
    reference_time_samples: int = param(256, "", "nit of the reference", min=3, max=16384)
    reference_check: bool = param(True, "", "re-solve the reference's peak with 2×nit, 1.5×Nh and a larger ε and "
                                            "report how much it moves (its own uncertainty: the nit and Nh trials)")
    nh_check: bool = param(True, "", "re-solve each variant's peak (and march the wear again) with 1.5×Nh and "
                                     "report how much it moves: the convergence measure of every FRF and wear "
                                     "result (a warning above 1e-3); with a reference (hb.reference_harmonics "
                                     "> 0) the variants are measured by their error against it and only the "
                                     "reference is re-solved")
    refine_peak: bool = param(True, "", "refine the headline peak between its grid neighbours (bounded scalar "
                                        "search to 1e-6 of f, ~10–25 extra solves of one variant); false: the "
                                        "grid's largest point is the headline peak")
    branch_check: bool = param(True, "", "re-solve the headline peak, the Nh-check's points and the sweep's last "
                                         "point from an independent start (tied; continuation in Nh from Nh = 1 "
                                         "where that disagrees) and warn if the swept root differs by more than "
                                         "1e-3: a sweep can follow a spurious root of the truncated balance that "
                                         "the Nh- and ε-checks, which start from it, cannot see")
    stability: bool = param(False, "", "Floquet stability of every converged point (monodromy of the linearised "
                                       "HB solution with the stick anchors as states; frf.csv stable, floquet_max; "
                                       "unstable points circled on the FRF figures); about a fifth of the sweep's "
                                       "time (docs/stability-and-modes.md)")
    time_check: bool = param(True, "", "integrate the headline peak in physical time from its HB state (rigid "
                                       "Coulomb contact, the reduced model) and fail the run (exit 3) if it is "
                                       "not a periodic orbit within the check's tolerance: a spurious HB root is "
                                       "not (~12 % of the FRF study's time)")

    def check(self):
        for nh in self.harmonics:
            for nit in self.time_samples:
                if "hdhb" in self.methods and nit not in (0, 2 * nh + 1) and len(self.methods) == 1:
                    raise SceneError(f"hb.time_samples = {nit} with hb.methods = ['hdhb']: HDHB needs "
                                     f"2Nh+1 = {2 * nh + 1} samples (use 0)")
                if nit and nit < 2 * nh + 1:
                    raise SceneError(f"hb.time_samples = {nit} < 2·Nh+1 = {2 * nh + 1} for hb.harmonics = {nh}")
        nh = self.reference_harmonics
        if nh and self.reference_time_samples < 2 * nh + 1:
            # Like hb.time_samples: an error, not silently raised to 2Nh+1.
            raise SceneError(f"hb.reference_time_samples = {self.reference_time_samples} < 2·Nh+1 = {2 * nh + 1} "
                             f"for hb.reference_harmonics = {nh}")


@dataclass
class Sweep:
    f_start_hz: float = param(0.0, "Hz", "first frequency (0: 0.9 × the first tied bending frequency)", min=0.0)
    f_stop_hz: float = param(0.0, "Hz", "last frequency (0: 1.1 × the first tied bending frequency)", min=0.0)
    points: int = param(50, "", "frequencies in the sweep (paper: 50); with method = arclength, of the linear "
                                "reference curves only", min=1, max=100000)
    method: str = param("grid", "", "grid: the fixed frequencies, secant predictor (the error table compares "
                                    "points); arclength: pseudo-arclength continuation from f_start to f_stop, "
                                    "step control, follows turning points",
                        choices=("grid", "arclength"))
    max_steps: int = param(300, "", "arclength: continuation steps at most per variant", min=1)

    def check(self):
        if self.f_start_hz and self.f_stop_hz and self.f_stop_hz <= self.f_start_hz:
            raise SceneError(f"sweep.f_stop_hz = {self.f_stop_hz} must exceed sweep.f_start_hz = {self.f_start_hz}")


@dataclass
class PseudoTime:
    scheme: str = param("ser", "", "pseudo-time integrator of the pseudo-time HB solver (hb.solver = "
                                   "\"pseudo-time\", workflow/engine/pseudotime.py); the wear system has one integrator, "
                                   "ser (linearly implicit), and refuses the others",
                        choices=("rk4", "local", "ser", "bdf", "radau", "lsoda", "rosenbrock", "block-jacobi"))
    precond: str = param("jacobian", "", "pseudo-time mass M of M ∂x/∂t* = −R: none (paper eq. 18), jacobi "
                                         "(local steps), jacobian (J(x0) frozen: pseudo-transient continuation, "
                                         "a damped Newton; attracting near resonance)",
                         choices=("none", "jacobi", "jacobian"))
    cfl: float = param(0.8, "", "explicit schemes (rk4, local): fraction of the measured stability limit (eq. 19)",
                       min=0.0, min_exclusive=True)
    max_steps: int = param(2000, "", "wear system: pseudo-time steps at most (the HB solver's pseudo-time "
                                     "attempts take max(200, hb.max_iterations) each)", min=1)
    dt_growth: float = param(1.0, "", "ser/block-jacobi: smallest growth factor of the pseudo-time step per "
                                      "accepted step (1: pure SER)", min=1.0)
    wear_dt_max: float = param(0.0, "blocks", "wear system: largest pseudo-time step in blocks of "
                                              "wear.cycles_per_block; 0: uncapped (the step control follows the "
                                              "wear trajectory)", min=0.0)
    wear_rtol: float = param(1e-3, "", "wear system: local error of a pseudo-time step on W, relative to "
                                       "max(max W, normal interpenetration) (the worn profile is the end of the "
                                       "trajectory: smaller = closer to the physical path; at 3e-3 the path "
                                       "error reached the wear checks' 1e-3 tolerance, docs/contact-layout.md)",
                             min=0.0, min_exclusive=True)


@dataclass
class Wear:
    k_w: float = param(1e-13, "m²/N", "Archard wear coefficient (per unit slip, per unit pressure)", min=0.0)
    blade_share: float = param(0.5, "", "fraction of the wear depth on the blade flank (rest on the disk)",
                               min=0.0, max=1.0)
    methods: list = param(["pseudo-time", "implicit"], "", "wear methods",
                          item_choices=("pseudo-time", "explicit", "implicit"))
    cycles_per_block: float = param(1e5, "cycles", "physical cycles per reference block (fixed blocks, "
                                                   "block_tol = 0); past cycles_per_block/steady_tol cycles a "
                                                   "march whose wear grows as under persistent slip stops",
                                    min=0.0, min_exclusive=True)
    max_blocks: int = param(400, "", "reference marching blocks at most", min=1)
    block_tol: float = param(0.01, "", "reference: adaptive blocks wearing at most this fraction of "
                                       "max(max W, normal interpenetration) each (resolves the wear dynamics; "
                                       "0: fixed blocks of cycles_per_block)", min=0.0)
    steady_tol: float = param(1e-4, "", "steady state: the wear still to come, extrapolated from the decay of "
                                        "the largest wear rate over the last doubling of cycles, below this "
                                        "fraction of the max wear", min=0.0, min_exclusive=True)
    reference_check: bool = param(False, "", "also march the reference with 4 × block_tol: its own convergence "
                                             "and, by Richardson extrapolation (first order in the block), the "
                                             "error of every method against its CPU time")
    frequency_hz: float = param(0.0, "Hz", "excitation frequency of the wear study with operating_point = "
                                            "\"frequency\" (0: first tied resonance)", min=0.0)
    operating_point: str = param("frequency", "", "where the wear study vibrates: \"frequency\" (frequency_hz, the "
                                                  "paper's §5.2 setting), \"detuning\" (detuning × the model's own "
                                                  "friction-damped resonance, found by an FRF search), \"resonance\" "
                                                  "(a dwell: the excitation follows the peak of the wearing system) "
                                                  "or \"mission\" (a duty cycle of detunings, wear.mission); "
                                                  "docs/wear.md",
                                 choices=("frequency", "detuning", "resonance", "mission"))
    detuning: float = param(1.0, "", "f / f_r with operating_point = \"detuning\" (1: at the friction-damped peak)",
                            min=0.5, max=2.0)
    mission: list = param([], "", "the duty cycle with operating_point = \"mission\": [[f / f_r, share of the "
                                  "cycles], …], f_r the new model's friction-damped resonance, f / f_r within 0.5–2, "
                                  "shares ≥ 0 summing to 1; their share-weighted wear rates drive one worn steady "
                                  "state (e.g. [[1.0, 0.1], [0.98, 0.9]])")
    dwell_tol: float = param(1e-5, "", "operating_point = \"resonance\": the dwell ends when a stage reaches its worn "
                                       "steady state and the peak of the worn system lies within this fraction of "
                                       "the stage's frequency", min=0.0, min_exclusive=True)
    dwell_step: float = param(3e-4, "", "operating_point = \"resonance\": the move of the peak (fraction of the "
                                        "frequency) a stage of the dwell aims at before the peak is found again; "
                                        "smaller follows the peak more closely (docs/wear.md)",
                              min=0.0, min_exclusive=True)
    dwell_stages: int = param(100, "", "operating_point = \"resonance\": stages of the dwell at most (each one march "
                                       "and one FRF search for the peak)", min=1)
    measure_length_m: float = param(2e-3, "m", "ℓ of the filtered worn profile among the wear measures (volume, "
                                               "scar, RMS depth)", min=0.0)
    length_m: float = param(0.0, "m", "length scale of the wear law: the frictional power per unit area averaged "
                                      "over ℓ on each flank (a Gaussian weighted by the tributary areas) before "
                                      "Archard's law; 0: node-wise, the paper's eq. 21 (docs/wear.md)", min=0.0)
    length_over: str = param("slip", "", "length_m > 0: how the rate takes ℓ — \"pressure\" (each pair wears "
                                        "under its own pressure capped at the mean pressure within ℓ; continuous "
                                        "where a pair starts or stops slipping), \"slip\" (only pairs that slip in "
                                        "contact wear, at the mean over the slipping pairs within ℓ) or \"all\" "
                                        "(a stuck pair wears beside slipping ones); docs/wear.md",
                             choices=("pressure", "slip", "all"))
    response_detunings: list = param([], "", "the wear response curve: the worn steady state at each f / f_r "
                                             "(f_r the friction-damped resonance), e.g. [0.98, 0.99, 1.0, 1.01]; "
                                             "[]: none (one pseudo-time march a point)", min=0.5, max=2.0)
    response_refine: int = param(4, "", "the wear response curve's peak: bisections of its cliff, the neighbouring "
                                        "points between which the wear starts to drag the resonance through the "
                                        "excitation (f / f_r,worn crosses 1; needs resonance_shift), each one "
                                        "more march; the bracket shrinks 2× a bisection (docs/wear.md)",
                                 min=0, max=20)
    resonance_shift: bool = param(True, "", "find the friction-damped resonance of the worn and the new model "
                                            "(worn − new shift in summary.json; two FRF searches)")
    control: str = param("force", "", "what the wear study holds: \"force\" (the scene's excitation, the "
                                      "paper's setting) or \"amplitude\" (the tip's first-harmonic amplitude "
                                      "tip_amplitude_m, the force scaled to it as the blade wears; well posed next "
                                      "to a resonance, docs/wear.md)", choices=("force", "amplitude"))
    tip_amplitude_m: float = param(0.0, "m", "control = \"amplitude\": the held tip amplitude (first harmonic, "
                                             "norm over the observed DOFs); 0: the new blade's response to the "
                                             "scene's force at the operating point", min=0.0)

    def check(self):
        if self.control == "amplitude" and self.operating_point in ("resonance", "mission"):
            raise SceneError(f"wear.control = \"amplitude\" with wear.operating_point = {self.operating_point!r}: a "
                             "held amplitude wears at one frequency (\"frequency\" or \"detuning\"); the dwell "
                             "and the mission are force-controlled")
        if self.operating_point != "mission":
            if self.mission:
                raise SceneError(f"wear.mission is set but wear.operating_point = {self.operating_point!r}: set "
                                 "wear.operating_point = \"mission\" to wear under the duty cycle, or drop wear.mission")
            return
        if not self.mission:
            raise SceneError("wear.mission is empty: wear.operating_point = \"mission\" needs the duty cycle, e.g. "
                             "wear.mission = [[1.0, 0.1], [0.98, 0.9]] ([f / f_r, share of the cycles] each)")
        for k, item in enumerate(self.mission):
            numbers = isinstance(item, list) and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                     and math.isfinite(v) for v in item)
            if not numbers or len(item) != 2:
                raise SceneError(f"wear.mission[{k}] = {item!r}: each point is [f / f_r, share of the cycles], "
                                 "two finite numbers")
            if not 0.5 <= item[0] <= 2.0:
                raise SceneError(f"wear.mission[{k}]: f / f_r = {item[0]!r} is outside 0.5–2")
            if item[1] < 0:
                raise SceneError(f"wear.mission[{k}]: share {item[1]!r} must be ≥ 0 (a fraction of the cycles)")
        total = math.fsum(item[1] for item in self.mission)
        if abs(total - 1.0) > 1e-9:
            raise SceneError(f"wear.mission: the shares sum to {total:.12g}, not 1 (within 1e-9): they are the "
                             "fractions of the cycles spent at each point")


@dataclass
class Remap:
    smoothing: str = param("harmonic", "", "mesh-motion extension into the bodies", choices=("harmonic", "elastic"))
    max_fraction: float = param(0.3, "", "largest node motion allowed, as a fraction of the local element size",
                                min=0.0, min_exclusive=True, max=1.0)
    reassemble: bool = param(True, "", "re-assemble and re-reduce the worn model, report frequency shifts")
    image_width: int = param(1600, "px", "figure width (the off-screen renderer's limit: 8192)", min=200, max=8192)


@dataclass
class Extreme:
    cases: list = param(["all"], "", "case groups to run: all, or any of penalty, friction, excitation, contact, "
                                     "resolution, frequency, wear, conditioning, divergence",
                        item_choices=("all", "penalty", "friction", "excitation", "contact", "resolution",
                                      "frequency", "wear", "conditioning", "divergence"))
    methods: list = param(["hbm", "tcm", "hdhb"], "", "formulations of the matrix",
                          item_choices=("hbm", "tcm", "hdhb"))
    solvers: list = param(["newton", "powell", "pseudo-time"], "", "solvers of the matrix",
                          item_choices=("newton", "powell", "pseudo-time"))
    harmonics: int = param(3, "", "Nh of the base cases", min=0, max=256)
    time_samples: int = param(32, "", "nit of the base cases (HDHB always 2Nh+1)", min=1, max=16384)
    frequency_ratio: float = param(0.97, "", "base frequency / first tied resonance", min=0.0, min_exclusive=True)
    max_harmonics: int = param(31, "", "Nh of the high-order case", min=1, max=256)
    max_time_samples: int = param(1024, "", "nit of the fine time-grid case", min=3, max=16384)
    penalty_decades: int = param(3, "", "ε from 10^-d to 10^d × the reference stiffness", min=0, max=12)
    wear_k: float = param(1e-11, "m²/N", "Archard coefficient of the very-large-wear case", min=0.0,
                          min_exclusive=True)
    wear_blocks: int = param(30, "", "blocks at most of the reference wear march", min=1)
    pseudo_steps: int = param(400, "", "pseudo-time steps at most", min=1)

    def check(self):
        if self.max_time_samples < 2 * self.harmonics + 1:
            raise SceneError(f"extreme.max_time_samples = {self.max_time_samples} < 2·extreme.harmonics+1 = "
                             f"{2 * self.harmonics + 1}")


@dataclass
class Scaling:
    factors: list = param([1.6, 1.3, 1.0, 0.8, 0.65], "", "mesh-size factors of the default sector, coarse to fine "
                                                         "(the three mesh sizes scaled; DOFs grow like factor⁻³)",
                          min=0.0, min_exclusive=True)
    procs: list = param([1, 2], "", "MPI process counts for assembly and reduction (the first is the reference)",
                        min=1)
    modes: int = param(30, "", "fixed-interface modes of the reduction", min=1)
    max_gb: float = param(20.0, "GB", "stop before a mesh whose extrapolated peak memory (all ranks) exceeds this",
                          min=0.0, min_exclusive=True)
    fit_min_dofs: int = param(20000, "", "power-law fits use the meshes with at least this many DOFs", min=0)


@dataclass
class NonlinearModes:
    mode: int = param(0, "", "tied mode whose nonlinear mode is followed (0: the lowest)", min=0)
    harmonics: int = param(7, "", "Nh of the EPMC", min=1, max=256)
    time_samples: int = param(0, "", "nit per period (0: the smallest power of 2 ≥ 4(2Nh+1), at least 64)", min=0, max=16384)
    amplitude_range: list = param([0.1, 3000.0], "", "modal amplitudes of the backbone, in units of the first "
                                                     "slip onset of the tied mode (from, to)", min=0.0)
    points: int = param(41, "", "backbone points at least (log-spaced in amplitude)", min=3)
    max_steps: int = param(80, "", "continuation steps at most (each a Newton solve of the whole EPMC system; "
                                    "a backbone that cannot turn a corner spends them there)", min=1)
    synthesis_forces: list = param([], "N", "tip forces at which the single-mode synthesis is compared with the "
                                            "direct HB FRF ([]: excitation.amplitude)", min=0.0)
    jenkins_check: bool = param(True, "", "also check, on a Jenkins oscillator, the EPMC against its "
                                          "multi-harmonic reference and the Floquet multiplier against "
                                          "event-driven shooting (≈ 3 s)")

    def check(self):
        if len(self.amplitude_range) != 2 or not 0 < self.amplitude_range[0] < self.amplitude_range[1]:
            raise SceneError(f"nonlinear_modes.amplitude_range = {self.amplitude_range}: two increasing positive "
                             "numbers (× the slip onset)")
        if self.time_samples and self.time_samples < 2 * self.harmonics + 1:
            raise SceneError(f"nonlinear_modes.time_samples = {self.time_samples} < 2·Nh+1 = "
                             f"{2 * self.harmonics + 1}")


@dataclass
class Verification:
    cases: list = param(["coulomb", "coulomb-damped", "coulomb-stop", "2dof-damper"], "",
                        "friction cases with exact references (workflow/verification/suite.py); pad-chain adds a "
                        "lumped cantilever with 8 root pads (≈ 12 s of time integration)",
                        item_choices=("coulomb", "coulomb-damped", "coulomb-stop", "2dof-damper", "pad-chain"))
    harmonics: list = param([1, 3, 7, 15], "", "numbers of harmonics Nh of the project's HB", min=1, max=256)
    time_samples: int = param(0, "", "nit per period (0: the smallest power of 2 ≥ 4(2Nh+1), at least 64)",
                              min=0, max=16384)
    penalty_factor: float = param(0.0, "", "ε_N = ε_T = this × the case's stiffness (k, or the stiffest pad); "
                                           "0: the project's default penalty", min=0.0)
    wear_cases: list = param(["jenkins", "punch", "punch-layer", "mdr"], "",
                             "wear references (workflow/verification/wear_exact.py, "
                             "wear_mdr.py): jenkins (one Jenkins element whose wear relieves "
                             "its load, closed form), punch (a rigid punch on three contacts "
                             "with an edge gap, closed form), punch-layer (the same punch "
                             "built through the contact's interface layer), mdr (the partial-slip worn "
                             "steady state of a Hertzian contact, closed form by the method "
                             "of dimensionality reduction, against a cycle-by-cycle march; "
                             "≈ 1.5 s), oscillator (a dynamic Jenkins oscillator by "
                             "event-driven integration with cycle jumps, ≈ 2 min)",
                             item_choices=("jenkins", "punch", "punch-layer", "oscillator", "mdr"))

    def check(self):
        for nh in self.harmonics:
            if self.time_samples and self.time_samples < 2 * nh + 1:
                raise SceneError(f"verification.time_samples = {self.time_samples} < 2·Nh+1 = {2 * nh + 1} for "
                                 f"verification.harmonics = {nh}")


@dataclass
class ContactConvergence:
    nodes_along: list = param([4, 7, 10], "", "flank vertices along x of each contact mesh, coarse to fine "
                                              "(geometry.contact_nodes chooses the layout)", min=2)
    nodes_across: list = param([2, 3, 4], "", "flank vertices across the flank, one entry per contact mesh", min=2)
    harmonics: int = param(1, "", "Nh of the FRF peak and wear solves; the problem has (2Nh+1)·3·pairs "
                                  "unknowns, solved by dense LU below 500 of them and by the structured, "
                                  "matrix-free Newton solve above (docs/solver-guide.md)", min=0, max=256)
    wear_harmonics: int = param(0, "", "Nh of the wear marches alone (0: harmonics); the worn steady state "
                                       "may converge in Nh sooner than the FRF peak — a wear step solves the "
                                       "augmented system by dense LU below 500 HB unknowns and matrix-free "
                                       "above (workflow/engine/wear/structured.py)", min=0, max=256)
    time_samples: int = param(32, "", "nit per period (≥ 2Nh+1)", min=1, max=16384)
    band: float = param(0.1, "", "peak search band: ± this fraction of the first tied frequency", min=0.0,
                        min_exclusive=True, max=0.5)
    points: int = param(9, "", "frequencies of the coarse grid that brackets the peak", min=3)
    peak_xtol: float = param(2e-5, "", "peak frequency tolerance of the bounded search, relative to the first "
                                       "tied frequency", min=0.0, min_exclusive=True)
    profile_points: list = param([41, 9], "", "common flank points (along, across) per flank where the worn "
                                              "profiles of all meshes are compared", min=2)
    wear: bool = param(True, "", "also compute the worn profile (pseudo-time wear) of every mesh")
    wear_max_pairs: int = param(0, "", "compute the worn profile only on the meshes with at most this many "
                                       "pairs (0: every mesh); the wear is compared between the finest meshes "
                                       "that have it", min=0)
    wear_amplitude: float = param(0.0, "N", "tip force of the wear solves (0: excitation.amplitude, the same "
                                            "as the FRF peak); the model is linear in the load, so its harmonic "
                                            "load vector is scaled", min=0.0)
    penalty_per_area: float = param(0.0, "N/m³", "DLFT penalties ε_N = ε_T = this × the pair's tributary area, "
                                                  "the same interface stiffness per unit area on every mesh (0: the "
                                                  "automatic per-pair penalty of [contact])", min=0.0)

    def check(self):
        if len(self.nodes_along) != len(self.nodes_across) or len(self.nodes_along) < 2:
            raise SceneError(f"contact_convergence.nodes_along ({len(self.nodes_along)} entries) and "
                             f"contact_convergence.nodes_across ({len(self.nodes_across)}) need the same length ≥ 2")
        if self.time_samples < 2 * self.harmonics + 1:
            raise SceneError(f"contact_convergence.time_samples = {self.time_samples} < 2·harmonics+1 = "
                             f"{2 * self.harmonics + 1}")
        if self.time_samples < 2 * self.wear_harmonics + 1:
            raise SceneError(f"contact_convergence.time_samples = {self.time_samples} < 2·wear_harmonics+1 = "
                             f"{2 * self.wear_harmonics + 1}")
        if len(self.profile_points) != 2:
            raise SceneError("contact_convergence.profile_points must be [along, across]")


@dataclass
class InterfaceScaling:
    pairs: list = param([16, 32, 64, 128, 256, 512], "", "contact pair counts (even: two flanks of "
                                                         "nodes_along × nodes_across ≥ 2 × 2 vertices each)", min=8)
    methods: list = param(["hbm", "hdhb"], "", "HB formulations", item_choices=("hbm", "tcm", "hdhb"))
    solvers: list = param(["newton"], "", "HB solvers (the cascade's)", item_choices=("newton", "pseudo-time"))
    harmonics: int = param(7, "", "harmonics Nh of every case", min=1, max=256)
    time_samples: int = param(64, "", "DLFT samples per period of HBM (HDHB uses 2·Nh+1)", min=3, max=16384)
    points: int = param(9, "", "frequencies of the fixed band through the first tied resonance (±10 %)", min=1)
    max_gb: float = param(8.0, "GB", "stop before a pair count whose extrapolated peak memory exceeds this",
                          min=0.0, min_exclusive=True)
    fit_min_pairs: int = param(64, "", "power-law fits use the cases with at least this many pairs", min=2)

    def check(self):
        if self.time_samples < 2 * self.harmonics + 1:
            raise SceneError(f"interface_scaling.time_samples = {self.time_samples} < 2·interface_scaling."
                             f"harmonics+1 = {2 * self.harmonics + 1}")
        for p in self.pairs:
            flank_grid(p)


def flank_grid(pairs: int) -> tuple[int, int]:
    """(nodes_along, nodes_across) per flank for ``pairs`` pairs over the two flanks:
    the most nearly square factorisation with both ≥ 2 (the geometry's minimum),
    along ≥ across (16 → 4×2, 512 → 16×16)."""
    m = int(pairs) // 2 if int(pairs) == pairs and pairs % 2 == 0 else 0
    div = [d for d in range(2, int(math.isqrt(max(m, 0))) + 1) if m % d == 0]
    if not div:
        raise SceneError(f"interface_scaling.pairs: {pairs} is not 2·a·b with a, b ≥ 2 "
                         "(two flanks of nodes_along × nodes_across ≥ 2 × 2)")
    return m // div[-1], div[-1]


@dataclass
class Cyclic:
    modes_per_nd: int = param(6, "", "modes of each nodal diameter (interface tied, disk clamped at the bore)", min=1)
    nodal_diameters: list = param([], "", "nodal diameters to solve ([]: all 0 … N/2; k > N/2 is folded to N − k, "
                                          "the same frequencies)", min=0, min_items=0)
    campbell_speeds_rpm: list = param([], "rpm", "rotation speeds of the Campbell diagram, K(Ω) re-assembled at "
                                                 "each with the ND-0 prestress ([]: no Campbell)", min=0.0, max=1e5,
                                 min_items=0)
    engine_order: int = param(1, "", "engine order EO of the travelling-wave excitation (harmonic n lives on ND "
                                     "n·EO mod N); drawn on the Campbell and ZZENF diagrams; cyclic-frf reads it",
                              min=0)
    engine_order_lines: list = param([], "", "further engine orders drawn as lines f = EO·Ω/2π on the Campbell "
                                             "diagram and whose crossings are listed", min=0, min_items=0)
    zzenf_band: float = param(0.05, "", "ZZENF: list the modes of each engine order's ND within this relative "
                                        "distance of f = EO·Ω/2π at rotation.speed_rpm", min=0.0,
                              min_exclusive=True, max=1.0)

    def check(self):
        # empty defaults leave the item type to this check (workflow/schema.py types items by the default's)
        for key, kind in (("nodal_diameters", int), ("engine_order_lines", int), ("campbell_speeds_rpm", float)):
            for v in getattr(self, key):
                if isinstance(v, bool) or not isinstance(v, (int, float)) or (kind is int and not isinstance(v, int)):
                    raise SceneError(f"cyclic.{key} contains {shown(v)}; its items must be "
                                     f"{'integers' if kind is int else 'numbers'}")
        if len(self.campbell_speeds_rpm) == 1:
            raise SceneError("cyclic.campbell_speeds_rpm needs at least 2 speeds for a Campbell diagram (or [])")


@dataclass
class Mistuning:
    stiffness: list = param([], "", "each blade's stiffness deviation δ_s (K_s = (1 + δ_s) K; one per blade, "
                                    "sector-major) — []: drawn from std and seed", min=-0.9, min_items=0)
    mass: list = param([], "", "each blade's mass deviation γ_s (M_s = (1 + γ_s) M; []: none)", min=-0.9,
                       min_items=0)
    std: float = param(0.02, "", "standard deviation of the drawn stiffness deviations (mistuning.stiffness = [])",
                       min=0.0, max=0.5)
    seed: int = param(1, "", "seed of the drawn pattern (the Monte Carlo's patterns use seed + 1 …)", min=0)
    blade_modes: int = param(10, "", "fixed-interface modes of the blade substructure", min=1)
    disk_modes: int = param(10, "", "fixed-interface modes of the disk per nodal diameter", min=1)
    harmonics: int = param(3, "", "Nh of the whole disk's HB", min=1, max=256)
    time_samples: int = param(0, "", "nit (0: the smallest multiple of N/gcd(N, EO) at or above the engine's "
                                     "default, so that every sector's delay is whole samples)", min=0, max=16384)
    band: float = param(0.03, "", "half-width of the friction grid's band around the tuned friction-damped "
                                  "peak (relative); the tied response and the peak search span twice it",
                        min=0.0, min_exclusive=True, max=0.5)
    points: int = param(7, "", "frequencies of the whole disk's grid (its largest blade peak refined between "
                               "them)", min=3)
    samples: int = param(0, "", "Monte Carlo patterns at mistuning.std (0: none; shared over MPI ranks)", min=0)
    checks: bool = param(True, "", "tuned whole disk against the cyclic sector, tied response against the "
                                   "assembled whole-disk model, lumped references (Whitehead, two blades); with "
                                   "mistuning.wear the tuned whole disk's worn state against the sector's")
    wear: bool = param(False, "", "the worn steady state of every blade's dovetail at the largest blade's "
                                  "friction-damped peak (the sector's wear law and march: [wear] k_w, "
                                  "blade_share, steady_tol; [pseudotime] max_steps, wear_rtol)")

    def check(self):
        for key in ("stiffness", "mass"):
            for v in getattr(self, key):
                if isinstance(v, bool) or not isinstance(v, (int, float)):
                    raise SceneError(f"mistuning.{key} contains {shown(v)}; its items must be numbers")


SECTIONS = {
    "run": Run, "model": Model, "material": Material, "rotation": Rotation, "damping": Damping,
    "excitation": Excitation, "modes": Modes, "reduction": Reduction, "contact": Contact, "hb": HB,
    "sweep": Sweep, "pseudotime": PseudoTime, "wear": Wear, "remap": Remap, "extreme": Extreme,
    "scaling": Scaling, "verification": Verification, "contact_convergence": ContactConvergence,
    "interface_scaling": InterfaceScaling, "cyclic": Cyclic, "nonlinear_modes": NonlinearModes,
    "mistuning": Mistuning,
}
