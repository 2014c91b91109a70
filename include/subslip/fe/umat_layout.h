/* The PROPS and STATEV layouts of umat_ (docs/fe.md), as 1-based Fortran indices.
 *
 * PROPS (units: stress as C11 and tau0, time as xi and eta_v; angles in degrees):
 *   POINT            1 single crystal, 2 Taylor aggregate of the grains listed from TAYLOR_GRAINS
 *   STRAIN           0 small strain (DSTRAN over DTIME), 1 finite strain (DFGRD0, DFGRD1)
 *   LATTICE          1 FCC {111}<110> (12 systems), 2 BCC {110}<111> (12),
 *                    3 BCC {110}+{112}<111> (24), 4 BCC {110}+{112}+{123}<111> (48),
 *                    5 HCP basal (0001)<11-20> (3) + prismatic {10-10}<11-20> (3) + pyramidal
 *                    {10-11}<11-20> (6) + pyramidal {10-11}<11-23> (12), c along z (24)
 *   C11, C12, C44    elastic constants (Voigt, as tabulated; HCP: C13, C33 in the tail)
 *   TAU0             reference stress of every slip system (CRSS = mu tau0); 0: one per
 *                    family, in the tail
 *   MU_S .. XI       friction coefficient evolution: mu_s, mu_k, kappa, xi
 *   U_FUNCTION       1 cot, 2 neg_log, 3 reciprocal;  U_TILDE
 *   OVERSTRESS       1 exponential, 2 power, 3 rate_independent;  ETA_V, N, R_HAT
 *   INITIAL_MU       0: mu_s
 *   Q_COPLANAR, Q_NON_COPLANAR   latent hardening (both 0: none, systems independent)
 *   LATTICE_ROTATION 0 finite (the lattice turns with the material), 1 none (small strain)
 *   TOLERANCE        flow-rule tolerance of the grain solver (0: 1e-12)
 *   MAX_ITERATIONS   Newton iterations of a grain step (0: 60)
 *   single crystal:  PHI1, PHI, PHI2 (Bunge Euler angles); NPROPS = 26
 *   Taylor:          TAYLOR_GRAINS = M, then per grain phi1, Phi, phi2, weight; NPROPS = 24 + 4 M
 * The tail, after those BASE = 26 (single crystal) or 24 + 4 M (Taylor) entries, at
 * PROPS(BASE + offset):
 *   HCP (LATTICE 5): HCP_C13, HCP_C33 (elastic constants), HCP_C_OVER_A (0: ideal, sqrt(8/3))
 *   TAU0 = 0:        then one tau0 per slip family, in the order above (FAMILIES(LATTICE))
 * NPROPS = BASE + TAIL(LATTICE, TAU0 = 0).
 *
 * STATEV: STATEV(MARKER) is 0 before the first call (the virgin state is then made from PROPS)
 * and 1 after; then one block of GRAIN_BLOCK(N) entries per grain (N slip systems), grain k
 * (from 0) starting at 2 + k GRAIN_BLOCK(N):
 *   +0..5   lattice-frame Cauchy stress, Mandel order (11, 22, 33, sqrt2 23, sqrt2 13, sqrt2 12)
 *   +6..14  orientation matrix g (v_crystal = g v_sample), row by row
 *   +15     the last step's length (where the next Newton iteration starts from)
 *   then N values each of mu, r_s, slip, slip rate, its trend and the trend's change.
 * NSTATV >= 1 + M GRAIN_BLOCK(N) (M = 1 for a single crystal). */
#ifndef SUBSLIP_FE_UMAT_LAYOUT_H
#define SUBSLIP_FE_UMAT_LAYOUT_H

#define SUBSLIP_UMAT_POINT 1
#define SUBSLIP_UMAT_STRAIN 2
#define SUBSLIP_UMAT_LATTICE 3
#define SUBSLIP_UMAT_C11 4
#define SUBSLIP_UMAT_C12 5
#define SUBSLIP_UMAT_C44 6
#define SUBSLIP_UMAT_TAU0 7
#define SUBSLIP_UMAT_MU_S 8
#define SUBSLIP_UMAT_MU_K 9
#define SUBSLIP_UMAT_KAPPA 10
#define SUBSLIP_UMAT_XI 11
#define SUBSLIP_UMAT_U_FUNCTION 12
#define SUBSLIP_UMAT_U_TILDE 13
#define SUBSLIP_UMAT_OVERSTRESS 14
#define SUBSLIP_UMAT_ETA_V 15
#define SUBSLIP_UMAT_N 16
#define SUBSLIP_UMAT_R_HAT 17
#define SUBSLIP_UMAT_INITIAL_MU 18
#define SUBSLIP_UMAT_Q_COPLANAR 19
#define SUBSLIP_UMAT_Q_NON_COPLANAR 20
#define SUBSLIP_UMAT_LATTICE_ROTATION 21
#define SUBSLIP_UMAT_TOLERANCE 22
#define SUBSLIP_UMAT_MAX_ITERATIONS 23
#define SUBSLIP_UMAT_PHI1 24
#define SUBSLIP_UMAT_PHI 25
#define SUBSLIP_UMAT_PHI2 26
#define SUBSLIP_UMAT_SINGLE_NPROPS 26
#define SUBSLIP_UMAT_TAYLOR_GRAINS 24
#define SUBSLIP_UMAT_TAYLOR_NPROPS(M) (24 + 4 * (M))
#define SUBSLIP_UMAT_LATTICE_HCP 5
#define SUBSLIP_UMAT_FAMILIES(LATTICE) ((LATTICE) <= 2 ? 1 : (LATTICE)-1)
/* Offsets after BASE (PROPS(BASE + offset)). */
#define SUBSLIP_UMAT_HCP_C13 1
#define SUBSLIP_UMAT_HCP_C33 2
#define SUBSLIP_UMAT_HCP_C_OVER_A 3
#define SUBSLIP_UMAT_HCP_TAIL 3
#define SUBSLIP_UMAT_TAIL(LATTICE, PER_FAMILY_TAU0)                      \
  (((LATTICE) == SUBSLIP_UMAT_LATTICE_HCP ? SUBSLIP_UMAT_HCP_TAIL : 0) + \
   ((PER_FAMILY_TAU0) ? SUBSLIP_UMAT_FAMILIES(LATTICE) : 0))

#define SUBSLIP_UMAT_MARKER 1
#define SUBSLIP_UMAT_GRAIN_BLOCK(N) (16 + 6 * (N))
#define SUBSLIP_UMAT_NSTATV(M, N) (1 + (M)*SUBSLIP_UMAT_GRAIN_BLOCK(N))

#endif
