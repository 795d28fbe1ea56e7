"""The engine's internal constants in one place (Box2D's ``constants.h``): numerical tolerances,
iteration limits and the thresholds of its algorithms, each with what it bounds and why it has
its value. What a user may tune is a ``Settings`` field instead (``settings``); these are not.

Every module imports its constants from here and nothing here imports from the package.
"""
import numpy as np


# ---- Free motion (``dynamics``, ``free_motion``)
ISOTROPIC_TOLERANCE = 1e-12  # relative spread of principal moments below which a body spins as a sphere
MAX_SPLIT_ANGLE = 0.25  # rad: largest non-commuting sub-rotation per sub-step (accuracy knob)
MAX_SUBSTEPS = 64  # beyond this, spin stays stable and L exact but accuracy degrades gracefully

# ---- Input checks (``validate``)
LENGTH_LIMIT = 1e12   # m: no length anywhere (a world bound, a shape, a plane offset) may exceed this, so
                      # products of a few lengths, speeds and masses stay far from overflow whatever the settings say
STAMP_LIMIT = 2.0 ** 32   # s: stamps beyond ±2³² s (year 2106 as Unix time) no longer resolve a microsecond in float64

# ---- Bodies (``world``)
DEFAULT_DENSITY = 1000.0  # kg/m³ (water), when neither mass nor density is given

# ---- Robots (``robot``)
LIMIT_TOLERANCE = 1e-9      # a joint position may exceed its limits by this much (round-off of the sender)
MIMIC_TOLERANCE = 1e-9      # a mimic joint's given position agreeing with its leader's this closely is accepted
CONVEX_MESH_TOLERANCE = 2e-3   # × its size: a collision mesh this close to its convex hull is that hull

# ---- Broad phase (``collision.broadphase``)
BRUTE_MAX = 32      # up to this many boxes, testing all N(N-1)/2 pairs at once is fastest
SAP_BUDGET = 16     # SAP while its sweep-axis candidates are ≤ this × N (+64), else the grid (measured
                    # crossover: ~20 candidates per box)
FAT_FRACTION = 0.2  # a fat box is the tight AABB grown by this × its largest half size
FAT_STEPS = 16      # and stretched along the body's displacement over this many steps at its velocity
                    # (Box2D v2's aabbMultiplier: a falling body keeps the cache for several steps)
FAT_STRETCH_MAX = 4.0  # each component of that stretch at most this × the box's largest half size

# ---- Narrow phase (``collision``)
TOUCH_TOLERANCE = 1e-9   # × the smaller body's size: a distance this short is touching, its direction noise
COINCIDE_FRACTION = 1e-6   # × a patch's size: two candidates this close are one place (one contact)
PROBE_WORK = 20000   # edge pairs × normals above which the edge query bounds each edge first (measured:
                     # the bound costs about what it saves on 32-point hulls, 30× less work on 1000-point ones)
LEAF_SIZE = 4    # triangles per leaf of a mesh's AABB tree (mesh_mesh): fewer, deeper trees; more, longer leaf loops
STACK = 256      # tree depth is log2(T / LEAF_SIZE) + 1: 256 covers any mesh that fits in memory

# ---- Contact response (``response``)
IMPACT_SPEED_FRACTION = 0.25  # approach slower than this × |g|·dt: no bounce, the resting solve holds it
REST_REBOUND_FRACTION = 0.5  # rebound slower than this × |g|·dt (airborne less than a step): it rests
IMPACT_ROUNDS = 128  # impact rounds per sub-step: contacts an impact's impulses turn into an approach get their own
                     # (compression, restitution), up to this many; what still approaches then rests. A light
                     # body between a heavy one and a wall takes about π√(M/m) impacts (Galperin's billiard):
                     # 43 at a mass ratio of 184, 99 at 1000
SIMULTANEOUS_FRACTION = 1e-6  # contacts closing within this × dt of an impact are hit together with it
SPECULATIVE_MAX_FRACTION = 0.5  # a body's look-ahead is at most this × its thinnest size (beyond: swept's job)
SPECULATIVE_MAX_TURN = 0.25     # rad: a body looks past that cap against a plane only while it turns less a step
MATCH_FRACTION = 0.1      # contacts of one pair within this × the smaller body's size are the same point
DIRECT_MAX_CONTACTS = 500       # default of settings.direct_max_contacts: the active set up to this many contacts
DIRECT_FIRST = 200              # above this many contacts in an island larger than DIRECT_ISLAND_MAX: Gauss–Seidel first
DIRECT_MAX_ROUNDS = 12          # active-set rounds before handing over to Gauss–Seidel
DIRECT_CONSISTENCY = 1e-7       # active rows must hold to this × the largest right-hand side, else the set is inconsistent
DIRECT_REGULARISATION = 1e-10   # relative diagonal shift: redundant contacts (4 points on a face) get the least-norm split
DIRECT_ISLAND_MAX = 128         # islands up to this many contacts: the compiled dense kernel (active_set); above, sparse
DIRECT_BAND_MIN = 8             # islands above this many contacts: each contact's coupling range only (active_set)
DIRECT_PIVOT_FRACTION = 1e-9    # a body-space factor's pivot below this × its diagonal: a freedom no active row fixes
DIRECT_FREEDOM_FLOOR = 1e-12    # and a freedom whose diagonal is below this × the island's largest (levers under
#                                 a micrometre, or a normal tilted by round-off): one no active row fixes either
DIRECT_REFINEMENTS = 2          # body-space solve: iterative refinements at most, while a row misses by more than
DIRECT_ROUNDOFF = 4 * 2.220446049250313e-16   # this × (its largest term: Delassus diagonal × impulse, or the rhs)
PGS_STALL_SWEEPS = 16   # Gauss–Seidel stops after this many sweeps without a new smallest residual (friction's cycle)
PGS_TOLERANCE = 1e-6   # relative: the stopping distance and hold are within 1e-3 of exact by then (tests)

# ---- Model choice (``response.models``)
PENALTY_OMEGA_DT_LIMIT = 1.0  # sqrt(k/m)·dt above this: the step cannot resolve the spring's oscillation
FRACTIONAL_AUTO_MAX_BODIES = 16   # toi auto: exact (fractional) times of impact for worlds this small with few dynamic bodies
FRICTION_CREEP_LIMIT = 1e-3   # m/s: penalty friction's regulariser above this lets held bodies creep visibly

# ---- Time of impact (``response.toi``, ``response.advancement``)
TOI_TOLERANCE = 1e-9   # × the smaller body's size: a pair this close counts as touching at its impact time
XTOL = 1e-15   # s: Brent's absolute tolerance on a time of impact
MAX_ADVANCES = 16      # conservative-advancement evaluations per pair and search, then bounded sampling
MAX_SAMPLES = 32       # samples of the rest of the interval when advancement is slow (its bound is loose)
TOI_DEEPEN = 0.1   # × the thinner body's thinnest size: a pair in contact sinking this much deeper within a
                   # sub-step is an event of its own (another corner of a spinning body swinging in)
RTOL = 4 * np.finfo(float).eps   # Brent's relative tolerance on the root
WIDE = 1e3     # the narrow phase's margin for a distance (m): pairs farther apart count as this far
MAX_BRENT = 100   # Brent iterations per root (it converges in a few dozen at XTOL, RTOL)
