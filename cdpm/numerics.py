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

# --------------------------------------------------------------------------
# statics and the input cone

#: statics hold when |L^T f + G + w_ext| <= STATICS_RTOL max(1 N, |G + w_ext|,
#: |L| |f|); a tension within STATICS_RTOL max(1, |f|) [N] of a bound sits on it
STATICS_RTOL = 1e-9
#: a given tension within this [N] (relative to max(1, |f|)) of a bound is on it
BOUND_TOLERANCE = 1e-9
#: singular values of L^T at most this times the largest are zero (equality
#: rows of the least-norm QP)
STATICS_RANK_RTOL = 1e-12
#: the batched least-norm solver: residual (relative to the statics' scale)
#: below which a pose is solved, and below which Newton steps stop
BATCH_STATICS_RTOL = 1e-11
BATCH_NEWTON_STOP_RTOL = 1e-13
#: the batched solver's Farkas gap (relative to max(1, |load|)) that proves
#: a pose has no equilibrium
FARKAS_RTOL = 1e-6

# --------------------------------------------------------------------------
# ranks and spans (pure LTI analysis)

#: singular values at most RANK_RTOL times the largest are zero (Krylov
#: bases, orthonormal bases, the rank of C with unit rows)
RANK_RTOL = 1e-10
#: rows of C shorter than this times the longest are zero (never reached)
ROW_ZERO_RTOL = 1e-12
#: angle-like tolerance of every positive-span decision [rad]
SPAN_TOL = 1e-9
#: columns shorter than this times the longest are zero in span decisions
ZERO_RTOL = 1e-11
#: batched rank exits: unit-column matrices whose singular-value ratio
#: exceeds this have full row rank beyond doubt (else the general path decides)
RANK_RATIO = 1e-6
#: ... and a ratio at most this is rank deficient beyond doubt
RANK_DEFICIENT_RATIO = 1e-14
#: Brammer: eigenvalues this close (absolute, after balancing) are one
EIG_ATOL = 1e-6
#: Brammer: |v^T b| at most this (for unit v and unit b) is zero
ZERO_ATOL = 1e-8

# --------------------------------------------------------------------------
# POC: modal path and margins

#: the modal path needs eigenvector matrices of K conditioned below this
MODAL_COND_MAX = 1e7
#: longest horizon of the modal path, in units of the slowest mode's period
HORIZON_MAX = 2e3
#: margin horizon: 3 periods (6 pi rad) of the slowest visible mode
SEE_PERIODS = 6 * math.pi
#: margin horizon requests beyond this many time units are tapered
HORIZON_MAX_UNITS = 1e3
#: margin horizon: growth of the impulse response allowed, by output count p
LOG_GROWTH = {1: math.log(1e8), 2: math.log(1e8), 3: math.log(1e6)}
#: ... and for p >= 4
LOG_GROWTH_HIGH = math.log(1e4)
#: margin: samples of the impulse response curve, by output count p
GRID_POINTS = {1: 256, 2: 64, 3: 32}
#: ... and for p >= 4
GRID_POINTS_HIGH = 64
