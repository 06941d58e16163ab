"""robustctl: a workbench for robust control of flexible structures.

``import robustctl as rc`` gives the whole public API, flat.

Architecture: floors that only look down
-----------------------------------------
A module imports only from its own floor (without a circle) and the floors below it,
function-level imports included; ``tests/test_architecture.py`` reads every import with
``ast`` and fails on an edge that points up or on a circle. Lowest first:

0. ``errors``, ``_version``, ``threads``, ``table``, ``executors``, ``_lapack`` -- the base
1. ``checks`` -- argument checks (imports only ``errors``); ``budget`` -- the time-budget
   policy and its ``Deadline`` (imports only ``errors`` and ``checks``)
2. ``frd``, ``frd_io``, ``plots`` -- FrequencyData, its file formats, plotting primitives
3. ``lti``, ``signals``, ``modes``, ``balanced`` -- systems and fast responses, named
   signals, ``Mode`` with MAC and pairing, balanced truncation
4. ``measure/`` (estimate, estimator, impact, impact_view, noise), ``cost`` (MACE eq. 5)
5. ``physical/``
6. ``interconnect``
7. ``correlate/``
8. ``identify/``
9. ``robust/``
10. ``export/``
11. the surface: ``figures``, ``report``, ``examples/``, ``demo*``, ``cli*``, this module

A method of a low-floor type whose work belongs higher up is registered by the higher
module when ``robustctl`` is imported (which always runs before any submodule):
``FrequencyData.save`` by ``frd_io`` and ``FrequencyData.plot``/``plot_sv`` by ``figures``
(:func:`robustctl.frd.register_method`); ``PhysicalModel.with_effect``'s ``Effect`` and
``candidates`` by ``physical.effects`` (:func:`robustctl.physical.model.register_effects`).
No submodule shares its name with a function or class that its package exports.
"""

# shared ground: one checks module, one system coercion, one cost report, one Mode
from . import checks, correlate, examples, robust, signals
from ._version import __version__ as __version__

# reproducibility: one time-budget policy (budget.py)
from .budget import BudgetWarning, Deadline
from .correlate import Comparison as Comparison
from .correlate import Diagnosis as Diagnosis
from .correlate import Residual
from .correlate import UpdateResult as UpdateResult
from .correlate import Verification as Verification
from .correlate import compare as compare
from .correlate import diagnose as diagnose
from .correlate import update as update
from .correlate import verify as verify
from .correlate.residual import UnitWarning
from .cost import LogCost, log_cost, log_error
from .errors import (
    DataError,
    DataWarning,
    FitError,
    ModelError,
    ParallelWarning,
    PlantError,
    RobustctlDeprecationWarning,
    RobustctlError,
    RobustctlWarning,
    SetupWarning,
    SynthesisError,
    SynthesisWarning,
)
from .export import ExportReport, discretize, export_controller, load_controller
from .export.controller import ExportWarning
from .figures import (
    ModeAnimation,
    animate_mode_shape,
    fit_percent,
    mac_matrix,
    plot_compare,
    plot_mac,
    plot_mode_shapes,
    plot_singular_values,
)
from .frd import Experiment, FrequencyData
from .frd_io import load_frd

# the user's FE model and test geometry: Nastran files, UFF geometry and mode shapes
from .frd_io.geometry import Geometry, ModeShapes
from .frd_io.uff_geometry import load_uff_geometry, load_uff_modes, write_uff_geometry
from .identify import (
    IdentifyWarning,
    MeasurementModel,
    PoleEvidence,
    StabilisationDiagram,
    balanced_truncation,
    combine_simo,
    fit_measurement_model,
    fit_rational,
    group_modes,
    pole_evidence,
)
from .interconnect import PartitionedPlant, block_diagonal, feedback, lft, parallel, series, star, upper_lft
from .lti import as_statespace, freqresp, is_stable
from .measure import estimator
from .measure.estimate import (
    EstimateWarning,
    HeldCommand,
    advised_nperseg,
    combine_experiments,
    estimate_frf,
    simulate_experiment,
)
from .measure.impact import ImpactWarning, estimate_frf_impact
from .measure.noise import NoiseModel, noise_model
from .modes import Mode
from .physical import (
    Frame,
    MatrixStructure,
    Parameter,
    PhysicalModel,
    Stage,
    StructuralMatrices,
    Structure,
    effects,
    electronics,
    frame_model,
    modal_model,
    modal_statespace,
    structural_model,
)
from .physical.ansys_import import (
    load_ansys_geometry,
    load_ansys_matrices,
    load_ansys_modes,
    read_ansys_matrices,
    read_ansys_modes,
)
from .physical.fe_model import fe_modal_model, fe_structural_model
from .physical.nastran_import import (
    load_bdf_geometry,
    load_nastran_matrices,
    load_nastran_modes,
    read_nastran_matrices,
    read_nastran_modes,
    write_nastran_matrices,
    write_nastran_modes,
)

# large structures in reduced coordinates (physical/reduction.py)
from .physical.reduction import band_limited, reduction_error
from .physical.uncertain import UncertainModel, parametric_lft
from .report import write_report

# robust design: weights
from .robust import (
    Block,
    BlockStructure,
    ControllerReduction,
    DesignReduction,
    DesignSweep,
    DKResult,
    GeneralizedPlant,
    HinfResult,
    MuResult,
    PlantWeight,
    UncertaintyCover,
    WorstCaseGain,
    Yardstick,
    YardstickWarning,
    as_block_structure,
    caltech_additive_weight,
    cover_additive,
    cover_multiplicative,
    cover_remainder,
    design_sweep,
    dksyn,
    fit_magnitude,
    generalized_plant,
    hinfnorm,
    hinfsyn,
    makeweight,
    mixed_sensitivity,
    robust_performance,
    robust_stability,
    worst_case_gain,
    yardstick,
)
from .robust import DiskMargin as DiskMargin
from .robust import DiskMarginResult as DiskMarginResult
from .robust import H2Result as H2Result
from .robust import LoopShapingResult as LoopShapingResult
from .robust import LQGResult as LQGResult
from .robust import disk_gain_phase as disk_gain_phase
from .robust import diskmargin as diskmargin
from .robust import h2norm as h2norm
from .robust import h2syn as h2syn
from .robust import lqg as lqg
from .robust import ncfsyn as ncfsyn
from .robust import nugap as nugap
from .robust import reduce_controller as reduce_controller
from .robust import sampled_plant as sampled_plant
from .robust import stability_margin as stability_margin
from .robust.analysis import RobustStabilityMargin, WorstCaseResult, robstab, wcgain
from .robust.continuous_equivalent import d2c
from .robust.conventions import LoopSignWarning
from .robust.mu import mu
from .robust.partitioned import as_partitioned
from .robust.uncertainty import (
    LFTAccuracyWarning,
    UncertainSystem,
    as_uncertain,
    physical_uncertain,
    ucomplex,
    ultidyn,
    ureal,
)
from .signals import combine_inputs as combine_inputs
from .signals import combine_outputs as combine_outputs
from .signals import rename_signals as rename_signals
from .signals import scale_inputs as scale_inputs
from .signals import scale_outputs as scale_outputs
from .signals import select_signals as select_signals
from .threads import blas_threads, set_blas_threads

__all__ = [
    # figures (the modal engineer's)
    "fit_percent",
    "write_report",
    "mac_matrix",
    "plot_compare",
    "plot_mac",
    "plot_mode_shapes",
    "plot_singular_values",
    "examples",
    *correlate.STAGE_NAMES,
    "effects",
    "Residual",
    "RobustctlError",
    "DataError",
    "ModelError",
    "FitError",
    "SynthesisError",
    "PlantError",
    "FrequencyData",
    "load_frd",
    # how the data were made
    "Experiment",
    "HeldCommand",
    "fit_rational",
    "combine_simo",
    "group_modes",
    "balanced_truncation",
    "fit_measurement_model",
    "MeasurementModel",
    "freqresp",
    "log_error",
    "log_cost",
    "estimate_frf",
    "combine_experiments",
    "simulate_experiment",
    "blas_threads",
    "set_blas_threads",
    "Parameter",
    "PhysicalModel",
    "Stage",
    "StructuralMatrices",
    "Structure",
    "Frame",
    "electronics",
    "frame_model",
    "structural_model",
    "modal_model",
    "modal_statespace",
    "MatrixStructure",
    # the user's FE model and test geometry (Nastran, UFF)
    "Geometry",
    "ModeShapes",
    "load_uff_geometry",
    "load_uff_modes",
    "write_uff_geometry",
    "fe_modal_model",
    "fe_structural_model",
    "animate_mode_shape",
    "ModeAnimation",
    "load_ansys_geometry",
    "load_ansys_matrices",
    "load_ansys_modes",
    "read_ansys_matrices",
    "read_ansys_modes",
    "load_bdf_geometry",
    "load_nastran_matrices",
    "load_nastran_modes",
    "read_nastran_matrices",
    "read_nastran_modes",
    "write_nastran_matrices",
    "write_nastran_modes",
    # large structures in reduced coordinates
    "band_limited",
    "reduction_error",
    # named interconnection (interconnect.py, signals.py) and the generalized plant (robust/plant.py)
    "PartitionedPlant",
    "lft",
    "upper_lft",
    "star",
    "series",
    "parallel",
    "feedback",
    *signals.__all__,
    "block_diagonal",
    "GeneralizedPlant",
    "PlantWeight",
    "generalized_plant",
    "mixed_sensitivity",
    # shared ground: one checks module, one system coercion, one cost report, one Mode
    "checks",
    "as_statespace",
    "LogCost",
    "Mode",
    # trust: the noise model of an estimate and the estimator's view of a model
    "estimator",
    "NoiseModel",
    "noise_model",
    "discretize",
    "export_controller",
    "load_controller",
    "ExportReport",
    # identification at modal-test scale
    "estimate_frf_impact",
    "ImpactWarning",
    "advised_nperseg",
    "StabilisationDiagram",
    # honest mode lists: the evidence that a fitted pole is a mode
    "PoleEvidence",
    "pole_evidence",
    # --- mu analysis (mu helper) ---
    "Block",
    "BlockStructure",
    "as_block_structure",
    "mu",
    "MuResult",
    "robust_stability",
    "caltech_additive_weight",
    "design_sweep",
    "DesignSweep",
    "robust_performance",
    "worst_case_gain",
    "WorstCaseGain",
    # robust design: weights
    "makeweight",
    "fit_magnitude",
    "cover_additive",
    "cover_multiplicative",
    "UncertaintyCover",
    # H-infinity norm and synthesis
    "hinfnorm",
    "hinfsyn",
    "HinfResult",
    # D-K iteration and the measurement-model yardstick
    "dksyn",
    "DKResult",
    "DesignReduction",
    "yardstick",
    "YardstickWarning",
    "Yardstick",
    # uncertain models from the update (parametric LFT) for mixed-mu D-G-K
    "UncertainModel",
    "parametric_lft",
    "cover_remainder",
    # H2/LQG, discrete synthesis, loop shaping, margins, controller reduction
    "is_stable",
    *robust.TOOLBOX_NAMES,
    "ControllerReduction",
    # reproducibility: the time-budget policy and robustctl's warning base
    "Deadline",
    "BudgetWarning",
    "RobustctlWarning",
    # the warning family: every warning robustctl issues derives from RobustctlWarning
    "SynthesisWarning",
    "DataWarning",
    "LoopSignWarning",
    "ParallelWarning",
    "SetupWarning",
    "RobustctlDeprecationWarning",
    "IdentifyWarning",
    "UnitWarning",
    "ExportWarning",
    "EstimateWarning",
    # one partitioned plant: the coercion shared by hinfsyn, h2syn, dksyn and the yardstick
    "as_partitioned",
    # uncertain elements and systems, robust stability and worst-case gain (robust/uncertainty)
    "ureal",
    "ucomplex",
    "ultidyn",
    "UncertainSystem",
    "as_uncertain",
    "physical_uncertain",
    "LFTAccuracyWarning",
    "LoopSignWarning",
    "robstab",
    "RobustStabilityMargin",
    "wcgain",
    "WorstCaseResult",
    # the continuous original of a sampled system (ZOH or Tustin inverse)
    "d2c",
]
