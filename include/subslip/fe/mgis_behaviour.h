/* The MFront generic-behaviour interface of libsubslip_fe, as MGIS (MFrontGenericInterfaceSupport)
 * loads it: the behaviour SubslipFCC, an FCC single crystal ({111}<110>, 12 slip systems) of
 * the subloading-overstress friction law at finite strain (docs/fe.md).
 *
 * The data structure below is declared from the public description of MFront's generic
 * interface (the header MFront/GenericBehaviour/BehaviourData.h of TFEL): its layout, not its
 * code. Reals are double. */
#ifndef SUBSLIP_FE_MGIS_BEHAVIOUR_H
#define SUBSLIP_FE_MGIS_BEHAVIOUR_H

#ifdef __cplusplus
extern "C" {
#endif

/* The state at the end of the step (and, with const arrays, at its start). */
typedef struct {
  const double* gradients;      /* F, TFEL tensor order F11 F22 F33 F12 F21 F13 F31 F23 F32 */
  double* thermodynamic_forces; /* Cauchy stress, TFEL order 11 22 33 r12 r13 r23, r = sqrt2 */
  const double* mass_density;
  const double* material_properties;
  double* internal_state_variables;
  double* stored_energy;
  double* dissipated_energy;
  const double* external_state_variables;
} mfront_gb_State;

typedef struct {
  const double* gradients;
  double* thermodynamic_forces;
  const double* mass_density;
  const double* material_properties;
  const double* internal_state_variables;
  const double* stored_energy;
  const double* dissipated_energy;
  const double* external_state_variables;
} mfront_gb_InitialState;

typedef struct mfront_gb_BehaviourData {
  char* error_message; /* a buffer of at least 512 characters, or NULL */
  double dt;
  /* In: K[0] what to compute (docs/fe.md), K[1] the stress measure (0: Cauchy), K[2] the
   * tangent operator (0: d sigma / d F). Out: the tangent operator, row major. */
  double* K;
  double* rdt; /* out: a factor for the next time step (below 1 on failure) */
  double* speed_of_sound;
  mfront_gb_InitialState s0;
  mfront_gb_State s1;
} mfront_gb_BehaviourData;

/* Returns 1 on success, -1 on failure (with a message in error_message). */
int SubslipFCC_Tridimensional(mfront_gb_BehaviourData* d);

#ifdef __cplusplus
}
#endif

#endif
