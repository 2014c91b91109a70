/* The PROPS and STATEV layouts of fric_ (docs/fe.md), as 1-based Fortran indices.
 *
 * PROPS (units: stress as the contact pressure, length as the slip, time as DTIME):
 *   MU_S, MU_K, KAPPA [1/length], XI [1/time]   friction coefficient evolution
 *   U_FUNCTION (1 cot, 2 neg_log, 3 reciprocal), U_TILDE [1/length]
 *   OVERSTRESS (1 exponential, 2 power, 3 rate_independent), ETA_V [time/length], N, R_HAT
 *   ALPHA_T   tangential contact stiffness [stress/length]
 *   INITIAL_MU (0: mu_s), INITIAL_R_S
 *   TOLERANCE flow-rule tolerance (0: 1e-12)
 *   NPROPS = 14
 *
 * STATEV (NSTATV >= 13): MARKER 0 before the first call (the state at rest is made from PROPS
 * and the pressure at the increment's start), 1 after; then the contact point's state: time,
 * total slip (2), slip path, viscoplastic slip path, viscoplastic slip rate, friction
 * coefficient mu, subloading ratio r_s, loading ratio r, normal traction at the end of the last
 * increment, traction (2, as written to TAU; TAU as passed in is the one used). */
#ifndef SUBSLIP_FE_FRIC_LAYOUT_H
#define SUBSLIP_FE_FRIC_LAYOUT_H

#define SUBSLIP_FRIC_MU_S 1
#define SUBSLIP_FRIC_MU_K 2
#define SUBSLIP_FRIC_KAPPA 3
#define SUBSLIP_FRIC_XI 4
#define SUBSLIP_FRIC_U_FUNCTION 5
#define SUBSLIP_FRIC_U_TILDE 6
#define SUBSLIP_FRIC_OVERSTRESS 7
#define SUBSLIP_FRIC_ETA_V 8
#define SUBSLIP_FRIC_N 9
#define SUBSLIP_FRIC_R_HAT 10
#define SUBSLIP_FRIC_ALPHA_T 11
#define SUBSLIP_FRIC_INITIAL_MU 12
#define SUBSLIP_FRIC_INITIAL_R_S 13
#define SUBSLIP_FRIC_TOLERANCE 14
#define SUBSLIP_FRIC_NPROPS 14

#define SUBSLIP_FRIC_MARKER 1
#define SUBSLIP_FRIC_TIME 2
#define SUBSLIP_FRIC_SLIP 3
#define SUBSLIP_FRIC_SLIP_PATH 5
#define SUBSLIP_FRIC_VP_SLIP 6
#define SUBSLIP_FRIC_VP_RATE 7
#define SUBSLIP_FRIC_MU 8
#define SUBSLIP_FRIC_R_S 9
#define SUBSLIP_FRIC_R 10
#define SUBSLIP_FRIC_PRESSURE 11
#define SUBSLIP_FRIC_TRACTION 12
#define SUBSLIP_FRIC_NSTATV 13

#endif
