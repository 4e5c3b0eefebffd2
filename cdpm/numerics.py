"""Every numerical threshold of cdpm, named once, each with its meaning.

The modules that decide things (statics, input cones, ranks, spans, POC,
margins, maps) read their thresholds here and nowhere else, so that a map
and the per-pose API decide with the same numbers. Relative tolerances are
relative to the scale named in their line; absolute ones carry their unit.

The public ``tol=`` arguments of the analysis functions (and of
:func:`cdpm.workspace_map`) default to :data:`SPAN_TOL`.
"""

from __future__ import annotations

import math

# --------------------------------------------------------------------------
# geometry and rigid bodies

#: a cable segment shorter than this [m] has no direction
MIN_SEGMENT_LENGTH = 1e-9
#: mass matrices whose condition number exceeds this are singular
MASS_COND_MAX = 1e12
#: a steering target past an output's range (the bound no pose goes past) by
#: more than this times the output's scale (at least 1) is out of reach
STEER_RANGE_RTOL = 1e-9

# --------------------------------------------------------------------------
# statics and the input cone

#: statics hold when |L^T f + G + w_ext| <= STATICS_RTOL max(|G + w_ext|,
#: |L| max(F, |f|)), F the robot's force scale (its weight: no absolute newton,
#: cdpm.model.robot.CableRobot.force_scale); a tension within STATICS_RTOL
#: max(F, |f|) [N] of a bound sits on it
STATICS_RTOL = 1e-9
#: a given tension whose statics residual is below this times max(|load|, its
#: largest entry) fails the statics by round-off only (printed digits,
#: float32); the refusal then says so
ROUNDED_RESIDUAL_RTOL = 1e-5
#: caller-given equilibrium tensions (cdpm.linearise, evaluate_poses, maps:
#: :func:`cdpm.dynamics.equilibrium.checked_tensions`): an entry beyond its
#: cable's bound by at most this times max(F, the largest |entry| of the
#: given tensions) is round-off and put on the bound; farther is an error.
#: The statics cannot tell such tensions apart (their tolerance is
#: STATICS_RTOL times |L| |f|), so this is STATICS_RTOL.
GIVEN_TENSION_BOUND_RTOL = STATICS_RTOL
#: singular values of L^T at most this times the largest are zero (equality
#: rows of the least-norm QP)
STATICS_RANK_RTOL = 1e-12
#: the batched least-norm solver: residual (relative to the statics' scale)
#: below which a pose is solved
BATCH_STATICS_RTOL = 1e-11
#: ... its Newton steps stop below this residual (relative to the pose's force
#: scale max(|load|, |L|_F F), F the robot's force scale)
BATCH_NEWTON_STOP_RTOL = 1e-13
#: ... Newton steps at most, and halvings of its backtracking line search
NEWTON_ITERATIONS = 25
NEWTON_HALVINGS = 16
#: the batched solver's Farkas gap (relative to the pose's force scale) that proves
#: a pose has no equilibrium
FARKAS_RTOL = 1e-6
#: the batched solver's ridge on L^T L (relative to its trace) and its
#: Levenberg-Marquardt damping far from the solution (relative to the trace)
NEWTON_RIDGE_RTOL = 1e-12
NEWTON_DAMPING = 1e-3

# --------------------------------------------------------------------------
# ranks and spans (pure LTI analysis)

#: singular values at most RANK_RTOL times the largest are zero (Krylov
#: bases, orthonormal bases, the rank of C with unit rows)
RANK_RTOL = 1e-10
#: rows of C shorter than this times the longest are zero (never reached)
ROW_ZERO_RTOL = 1e-12
#: angle-like tolerance of every positive-span decision [rad]
SPAN_TOL = 1e-9
#: the range of the largest |entry| of each of A, B and C that the per-pose
#: analysis takes (0 too): beyond it products of entries under- or overflow;
#: span vectors outside it are scaled into it by a power of two
MATRIX_SCALE_RANGE = (1e-100, 1e100)
#: columns shorter than this times the longest are zero in span decisions
ZERO_RTOL = 1e-11
#: batched rank exits: unit-column matrices whose singular-value ratio
#: exceeds this have full row rank beyond doubt (else the general path decides)
RANK_RATIO = 1e-6
#: ... and a ratio at most this is rank deficient beyond doubt
RANK_DEFICIENT_RATIO = 1e-14
#: batched rank exits: Krylov columns shorter than this times the longest are dropped
KRYLOV_COLUMN_NEGLIGIBLE = 1e-12
#: batched span exits leave to the analyser the systems whose angular deficit
#: is within this [rad] of ``tol`` (wrench closure: the same vectors, round-off apart)
WRENCH_DEFER_BAND = 1e-11
#: exits leave open the systems whose deciding numbers lie within this
#: fraction of their zero threshold (the analyser computes them in another order)
THRESHOLD_DEFER_FRACTION = 0.5
#: ... and the systems whose angular gap is within this of pi - tol [rad]
ANGULAR_DEFER_BAND = 1e-11
#: ... and, for Brammer's test on a linear image of -M^-1 L^T (which scales
#: small deficits by up to its condition number squared), deficits in this range [rad]
BRAMMER_DEFER = (1e-12, 1e-5)
#: Brammer: eigenvalues this close (absolute, after balancing) are one
EIG_ATOL = 1e-6
#: Brammer: |v^T b| at most this (for unit v and unit b) is zero
ZERO_ATOL = 1e-8

# --------------------------------------------------------------------------
# POC: modal path and margins

#: sample grids of the impulse response never assume a rate below this [1/time]
RATE_FLOOR = 1e-3
#: the closed-form evaluator of e^{At} needs eigenvector matrices (of the
#: scaled A) conditioned below this (the modal path: MODAL_PATH_COND_MAX)
MODAL_COND_MAX = 1e7
#: longest horizon of the modal path, in units of the slowest mode's period
HORIZON_MAX = 2e3
#: margin horizon: 3 periods (6 pi rad) of the slowest visible mode
SEE_PERIODS = 6 * math.pi
#: margin horizon requests beyond this many time units are tapered
HORIZON_MAX_UNITS = 1e3
#: longest margin horizon a caller may give, in the same time units (the
#: responses, sampled at a fixed number of times, overflow some way beyond)
HORIZON_GIVEN_MAX_UNITS = 1e6
#: a given horizon passes its bounds within this relative round-off (the
#: default horizon lies on the growth bound, computed in other coordinates)
HORIZON_BOUND_RTOL = 1e-9
#: margin horizon: growth of the impulse response allowed, by output count p
LOG_GROWTH = {1: math.log(1e8), 2: math.log(1e8), 3: math.log(1e6)}
#: ... and for p >= 4
LOG_GROWTH_HIGH = math.log(1e4)
#: margin: samples of the impulse response curve, by output count p
GRID_POINTS = {1: 256, 2: 64, 3: 32}
#: ... and for p >= 4
GRID_POINTS_HIGH = 64
#: reach margin: intervals of the piecewise-constant inputs on [0, T], by output
#: count p (the zonotope has m K generators; its facet candidates grow as
#: (m K)^(p-1))
REACH_NODES = {1: 64, 2: 32, 3: 12}
#: ... and for p >= 4
REACH_NODES_HIGH = 4
#: reach margin: the most work of one pose's facet search, C(N, p-1) facet
#: candidates times (N + p) for N generators in p output dimensions (the
#: compiled search prunes most of it); beyond it r_T is not
#: computed (NaN, with a NaN error bound)
REACH_MAX_FACET_WORK = 5e8
#: a facet candidate whose normal is shorter than this times the product of
#: its generators' lengths comes from dependent generators and is skipped
ZONOTOPE_NORMAL_RTOL = 1e-12
#: the facet search's upper bound of an inradius is raised by this times the
#: sum of the generators' lengths (their round-off), so that it never rules
#: out the least facet
ZONOTOPE_BOUND_RTOL = 1e-12
#: output Jacobian entries below this times the robot's size [m] are the
#: round-off of forward kinematics and set to 0 (a folded arm's tip on its
#: shoulder: 1e-16 for an arm metres long)
OUTPUT_JACOBIAN_ZERO_RTOL = 1e-12
#: reach margin: a zonotope inradius below this times the sum of its
#: generators' lengths, or times the reach scale (F / m) T^2 / 2, is
#: round-off, reported as 0
REACH_ZERO_RTOL = 1e-12
#: reach margin: the largest growth e^{Re(lambda) T} of a pose's modes
#: within the horizon; beyond it r_T is not resolvable (NaN)
REACH_GROWTH_MAX = 1e8
#: reach margin: the model's default horizon is shortened so that the
#: fastest-growing mode at the robot's reference pose grows by at most this
#: within it (the square root of REACH_GROWTH_MAX: poses whose modes grow
#: up to twice as fast resolve too)
REACH_DEFAULT_GROWTH = 1e4
#: default tension budget: the least characteristic acceleration [m/s^2]
#: (the budget accelerates the robot's mass by max(|g|, this))
REACH_MIN_ACCELERATION = 1.0
#: default reach horizon: the time in which that acceleration moves the
#: robot by this fraction of its size (the linearisation is a local model)
REACH_SIZE_FRACTION = 0.1
#: largest magnitude of gravity [m/s^2] and of each external load entry
#: [N or N m] a spec or an override may give (beyond, the dynamics overflow)
MAX_GRAVITY = 1e6
MAX_EXTERNAL_LOAD = 1e12
#: largest tension [N] a spec, an override or a caller may give: a cable's
#: bounds (a maximum may also be inf: no upper bound), a pretension, given,
#: simulated or capped tensions (beyond, sums of squares overflow)
MAX_TENSION = 1e12
#: longest time a reach horizon, a steering or a simulation may span [s]
#: (about 12 days; T^2 and the time grids stay far from overflow)
MAX_TIME_SPAN = 1e6
#: largest tension budget of the reach margin [N] (the margin grows with
#: it; sums of squares of its generators stay far from overflow)
MAX_TENSION_BUDGET = 1e12

# --------------------------------------------------------------------------
# regions of maps

#: seconds between progress lines of a map when stderr is not a terminal
PROGRESS_LOG_INTERVAL = 10.0

#: default neighbourhood radius of a sampled map, in mean nearest-neighbour
#: distances: in 2-D about 7 neighbours per sample, so that a uniform region
#: stays connected, while NO bands a few samples wide still separate regions
REGION_RADIUS_FACTOR = 3.0
#: default neighbourhood radius of a sampled map over one axis, in largest
#: gaps between consecutive samples: there only consecutive samples are
#: neighbours (so one NO sample separates), and random samples leave gaps
#: of several times their mean (about ln n times), which the mean-distance
#: radius above split into many false regions; twice the largest gap lets
#: an angle axis sampled over a full turn join across its seam
REGION_GAP_FACTOR = 2.0
#: relative tolerance (to the step) of "evenly spaced" and of a full turn
REGION_WRAP_RTOL = 1e-3
#: tolerance [rad or m] of a pose's coordinates that are not on a map axis
REGION_BASE_ATOL = 1e-6
#: safety factor on the Lipschitz bound of the reach margin r_T estimated from
#: sampled slopes: an edge of length h between neighbouring YES samples a, b
#: is suspect (a NO set thinner than the samples may cross it) when
#: r(a) + r(b) <= SUSPECT_LIPSCHITZ_SAFETY * L * h, L the largest slope
#: |r(x) - r(y)| / |x - y| over the sampled edges at a or b
SUSPECT_LIPSCHITZ_SAFETY = 2.0
#: POC neighbourhoods resample r_T at this many poses along each suspect
#: edge (the nearest first, up to as many poses as the grid has) and judge
#: the finer steps by the same rule: an edge whose finer steps all clear it
#: is not suspect
NEIGHBOURHOOD_REFINE_POINTS = 15

# --------------------------------------------------------------------------
# spec

#: consecutive route points on one frame within this [m] (+ allclose rtol 1e-5) coincide
SPEC_COINCIDENT_POINT_ATOL = 1e-12
#: a quaternion or (cos, sin) pair with norm within this of 1 is normalised, else refused
CONFIGURATION_UNIT_NORM_TOL = 1e-6

# --------------------------------------------------------------------------
# CASPR import

#: a cable segment shorter than this [m] at the named pose counts as degenerate
CASPR_MIN_SEGMENT = 1e-6
#: CASPR prismatic joint bounds beyond this [m], or missing, are clipped to it in the URDF
CASPR_UNBOUNDED_PRISMATIC = 1e3
#: a CASPR q_initial at most this [rad or m] beyond a joint limit is within it
CASPR_LIMIT_TOL = 1e-9
#: an output Jacobian row shorter than this [m per rad or m] does not move
CASPR_MOVING_OUTPUT_ATOL = 1e-9
#: output Jacobian singular values <= this times max(1, largest) are zero (rank check)
CASPR_OUTPUT_RANK_RTOL = 1e-9
#: a body moves with a singular mass matrix's null motion when its angular
#: speed [rad/s], or its centre of mass's speed over the robot's size, exceeds
#: this times the largest of them (the motion of unit norm)
CASPR_NULL_MOTION_RTOL = 1e-6

# --------------------------------------------------------------------------
# analysis (inline thresholds)

# linear algebra, spans and hulls
#: null spaces: singular values at most this times the largest are zero (the
#: default, and the floor of Brammer's eigenspace tolerance)
NULL_SPACE_RTOL = 1e-8
#: Krylov bases: new directions with singular values at most this times |A|_F
#: are round-off
KRYLOV_RTOL = 1e-9
#: A^2 = 0 when every entry of A^2 is at most this times that of |A| |A|
SQUARE_ZERO_RTOL = 1e-12
#: eigenvalues with |Im| at most this times the largest |eigenvalue| are real
#: (uncontrollable modes in Brammer's test, the stiffness eigenvalues of K)
REAL_EIG_RTOL = 1e-9
#: span decisions on unit columns: QR diagonals or singular values at most this
#: times the largest are zero (rank < p; also an oscillatory mode's input rows)
SPAN_RANK_RTOL = 1e-9
#: an NNLS residual at most this times max(1, |target|) is zero: the target is
#: in the cone
NNLS_RES_RTOL = 1e-10
#: a positive combination holds only when the smallest singular value of its
#: unit columns exceeds this (and 10 times its relative residual)
COMBINATION_SV_MIN = 1e-12
#: ... and when its smallest share w_i |s_i| / sum_k w_k |s_k| exceeds this
#: times its relative residual over that singular value: the least-norm
#: correction cancelling the residual changes no share by more than residual /
#: singular value, so an exact combination with positive weights exists (a
#: column taking part at round-off level proves nothing)
COMBINATION_SHARE_MARGIN = 2.0
#: a positive-span certificate's column whose weight is at most this times
#: the largest takes part at round-off (NNLS leaves such weights): it is
#: dropped, and the other weights corrected to cancel the residual
ROUNDOFF_SHARE_RTOL = 1e-9
#: least-distance programming: a residual component below this puts 0 in the hull
LDP_ZERO_ATOL = 1e-14
#: hulls and polar LPs drop vectors shorter than this times the longest
HULL_ZERO_RTOL = 1e-14
#: primal feasibility tolerance of the polar LPs of the margin bracket (DAQP)
POLAR_LP_PRIMAL_TOL = 1e-9
#: planar hulls: a cloud whose second-moment Schur complement is at most this
#: times its y moment is degenerate (not whitened)
WHITEN_REGULAR_RTOL = 1e-24

# responses, horizons and NO proofs (scaled system, |A| ~ 1)
#: default horizon: rates and frequencies at most this are zero
HORIZON_RATE_MIN = 1e-6
#: NO proofs: Taylor coefficients at most this times |v^T C| |b_j| are zero
TAYLOR_ZERO_RTOL = 1e-11
#: NO proofs: modal coefficients at most this times their sum are insignificant
MODE_COEFF_RTOL = 1e-12
#: NO proofs: modes within this of the slowest decay rate are dominant
DOMINANT_RATE_ATOL = 1e-9
#: NO proofs: eigenvalues with |Im| at most this are real
REAL_EIG_ATOL = 1e-12
#: NO proofs: round-off allowance of the sampled bound, times the modal magnitudes
GRID_ROUNDOFF_RTOL = 1e-13
#: sampled search: sample up to a modal dynamic range of e^this (~1e12; beyond
#: it double precision no longer resolves the slower directions)
LOG_DYNAMIC_RANGE = 27.0
#: sampled search: a spread of the eigenvalues' real parts at most this is none
SPREAD_MIN = 1e-12
#: modal sampled search: stop where the fastest growing mode has grown by e^this
MODAL_LOG_GROWTH = math.log(1e8)

# the POC pipeline and its paths
#: free-input samples shorter than this times the longest are round-off
FREE_SAMPLE_ZERO_RTOL = 1e-9
#: p free-input samples are robustly independent when the pivoted QR's |R_pp|
#: exceeds this times |R_11| (unit columns)
FREE_SPAN_RATIO = 1e-6
#: quick output-rank test: rank [CB, CAB] = p (unit rows and columns) when its
#: p-th singular value exceeds this times the largest
OUTPUT_RANK_QUICK_RATIO = 1e-8
#: a matrix whose condition number exceeds this is singular (the reduced C of
#: the Brammer path; Cq and eigenvector bases in re-checks)
INVERTIBLE_COND_MAX = 1e10
#: modal path: A's blocks within this (relative to max|A|; absolute for the
#: identity block) of [[0, I], [K, 0]]
MECHANICAL_BLOCK_RTOL = 1e-12
#: modal path: K's eigenvector matrix U needs |U|_F |U^-1|_F at most this
MODAL_PATH_COND_MAX = 1e8
#: modal path: stiffness eigenvalues kappa >= -this times K's scale are
#: sign-definite (|kappa| below it: neither oscillating nor growing)
KAPPA_ZERO_RTOL = 1e-9
#: modal path: stiffness eigenvalues closer than this times the largest |kappa|
#: are one cluster
KAPPA_CLUSTER_RTOL = 1e-8
#: modal path: the output rows span a K^T-invariant subspace when the residual
#: is at most this times |K|_F
INVARIANT_RTOL = 1e-9
#: modal path: modal input rows shorter than this times their input's size are zero
MODAL_ROW_ZERO_RTOL = 1e-10
#: modal path: modal coordinates with singular values above this (absolute, unit
#: scale) are seen by the outputs
VISIBLE_ATOL = 1e-8

# certificate re-checks
#: default tolerance of the re-check of a span certificate or a Brammer witness
RECHECK_TOL = 1e-7
#: Brammer witness: eigen-residual round-off allowance, times |v| |A| + |lambda| |v|
RECHECK_WITNESS_ROUNDOFF_RTOL = 1e-12
#: default tolerance of POCCertificate.verify
POC_RECHECK_TOL = 1e-6
#: certificate vectors match the recomputed g_j(t) to this times |g_j(t)|
RECHECK_VECTOR_RTOL = 1e-6
#: nilpotent separator: A^2 = 0 when every entry is at most this times |A| |A|
RECHECK_SQUARE_ZERO_RTOL = 1e-10
#: dense grid: round-off allowance of e^{At}, times |e^{At}| |C| |b_j|
RECHECK_EXPM_ROUNDOFF_RTOL = 1e-10
#: general separator (scaled system): Taylor coefficients above this are nonzero
RECHECK_TAYLOR_ATOL = 1e-9
#: general separator: modal coefficients above this times their sum are significant
RECHECK_MODE_RTOL = 1e-9
#: general separator: modes within this of the slowest decay rate are dominant
RECHECK_DOMINANT_ATOL = 1e-7
#: general separator: eigenvalues with |Im| at most this are real
RECHECK_REAL_ATOL = 1e-9
#: modal certificates: A's blocks within this (relative to max|A|; absolute for
#: the identity block) of [[0, I], [K, 0]]
RECHECK_MECHANICAL_RTOL = 1e-9
#: modal certificates: singular values of K^T - kappa I at most this times |K|_2
#: are zero, and distinct claimed eigenvalues differ by more
RECHECK_EIG_RTOL = 1e-7
#: modal certificates: an oscillatory mode's unit input rows have full rank when
#: their singular-value ratio exceeds this
RECHECK_MODAL_RANK_RTOL = 1e-8

# --------------------------------------------------------------------------
# choosing the tension (cdpm.dynamics.tension_choice)

#: primal and dual feasibility tolerance of the tension LPs (HiGHS), relative to
#: the pose's tension scale (max(F, the largest finite |bound|, the least-norm
#: tension), F the robot's force scale): the LPs solve in its units
TENSION_LP_TOL = 1e-9
#: ... or this times the LP's largest right-hand side (same units) when that is more
TENSION_LP_RTOL = 1e-13
#: a least or greatest feasible tension within this times the pose's tension
#: scale (max(F, the largest finite |bound|, the least-norm tension)) of a
#: cable's bound is on it; a cable whose feasible range is shorter than that
#: (relative to its greatest tension) is fixed by the statics
TENSION_RANGE_RTOL = 1e-8
#: default tension cap of cables without an upper bound in the tension search:
#: this many reach tension budgets F (the robot's weight, or its mass times
#: 1 m/s^2), or the largest finite maximum tension of a cable if larger
TENSION_CAP_BUDGETS = 10.0

# --------------------------------------------------------------------------
# model size (cdpm.model.robot)

#: most degrees of freedom (velocity coordinates nv: one per revolute or
#: prismatic joint, 6 per free flyer) of a model cdpm loads. Pinocchio's
#: data for a model takes about 64 nv^3 bytes (0.5 GB at 200, 64 GB at
#: 1,000 joints), a robot keeps one per thread and a map's worker processes
#: one each; a model with more is refused at load, before any is created
MAX_MODEL_DOF = 200

# --------------------------------------------------------------------------
# certified boxes (cdpm.certify)

#: absolute error bound of numpy's float64 sin and cos [1] on the arguments
#: cdpm certifies (|x| <= 1e5 rad): libm and numpy's SIMD versions are
#: within 4 units in the last place; this allows 8 units of 1.0. Interval
#: enclosures of sin and cos widen by it (cdpm.certify.interval)
CERTIFY_SINCOS_ERROR = 8 * 2.0**-52
#: certified boxes: a patch of directions is proven by a column whose angle
#: margin (w . g_j over |w| |g_j|, lower bounds over the patch and the box)
#: exceeds this [rad]: well above SPAN_TOL, within which the per-pose
#: analyser calls a set on the boundary NO
CERTIFY_ANGLE_MIN = 1e-6
#: certified boxes: the most direction patches of one box's YES proof
CERTIFY_MAX_PATCHES = 4096
#: certified boxes: the Neumann bound |I - M X| of the mass matrix over a box
#: (X the inverse of its midpoint) must stay below this
CERTIFY_NEUMANN_MAX = 0.9
#: certified boxes: candidate separators tried for a NO proof
CERTIFY_SEPARATOR_CANDIDATES = 720
#: loaded boxes (cdpm.certify.loaded): a cable's equilibrium tension is
#: proven inside or outside a bound only with a gap of this times the
#: tension scale (the robot's force scale, or the largest tension): a
#: thousand times the per-pose analyser's bound test (STATICS_RTOL), so the
#: equilibrium solvers' round-off cannot move a cable across it
CERTIFY_TENSION_GAP_RTOL = 1e-6
#: loaded boxes: the free cables' output directions C_q M^-1 L^T (unit
#: columns) must have a smallest singular value above this over the box:
#: a thousand times the analyser's rank thresholds (RANK_RATIO,
#: FREE_SPAN_RATIO), so it finds the same full rank at every pose
CERTIFY_FREE_RANK_MIN = 1e-3
