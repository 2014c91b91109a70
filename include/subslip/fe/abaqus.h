/* The entry points of libsubslip_fe (docs/fe.md): the Abaqus user subroutines UMAT and FRIC with
 * their Fortran argument lists, callable from C, C++ and Fortran. Every argument is passed by
 * reference as Fortran passes it; CHARACTER arguments add their lengths at the end of the list
 * (gfortran and ifort do so on Linux). Arrays are Fortran-ordered (column major).
 *
 * umat_ (also umat, UMAT): a single crystal or a Taylor aggregate at one integration point,
 * chosen by PROPS(1); the PROPS and STATEV layouts are in docs/fe.md. Units are those of PROPS
 * (stress as the elastic constants and tau0, time as xi and eta_v).
 * fric_ (also fric, FRIC): one frictional contact point of Hashiguchi's subloading-overstress
 * friction law.
 *
 * Both are safe to call from many threads at once. A step that cannot be taken (bad PROPS,
 * NSTATV too small, no convergence) sets PNEWDT below 1, leaves STRESS / TAU and STATEV as they
 * came in and prints one line naming the cause on stderr (subslip_fe_last_message returns it). */
#ifndef SUBSLIP_FE_ABAQUS_H
#define SUBSLIP_FE_ABAQUS_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

void umat_(double* stress, double* statev, double* ddsdde, double* sse, double* spd, double* scd,
           double* rpl, double* ddsddt, double* drplde, double* drpldt, const double* stran,
           const double* dstran, const double* time, const double* dtime, const double* temp,
           const double* dtemp, const double* predef, const double* dpred, const char* cmname,
           const int* ndi, const int* nshr, const int* ntens, const int* nstatv,
           const double* props, const int* nprops, const double* coords, const double* drot,
           double* pnewdt, const double* celent, const double* dfgrd0, const double* dfgrd1,
           const int* noel, const int* npt, const int* layer, const int* kspt, const int* jstep,
           const int* kinc, size_t cmname_length);

void fric_(int* lm, double* tau, double* ddtddg, double* ddtddp, double* dslip, double* sed,
           double* sfd, double* ddtddt, double* pnewdt, double* statev, const double* dgam,
           const double* taulm, const double* press, const double* dpress, const double* ddpddh,
           const double* slip, const int* kstep, const int* kinc, const double* time,
           const double* dtime, const int* noel, const char* ciname, const char* slname,
           const char* msname, const int* npt, const int* node, const int* npatch,
           const double* coords, const double* rcoord, const double* drot, const double* temp,
           const double* predef, const int* nfdir, const int* mcrd, const int* npred,
           const int* nstatv, const double* chrlngth, const double* props, const int* nprops,
           size_t ciname_length, size_t slname_length, size_t msname_length);

/* The STATEV entries umat_ needs for these PROPS (0 when the PROPS are refused, with the reason
 * in subslip_fe_last_message). */
int subslip_fe_umat_statev_count(const double* props, int nprops);
/* The last message of an entry point called on this thread (empty after a call that succeeded),
 * copied into buffer (NUL-terminated, cut at size - 1 characters); returns its full length. */
int subslip_fe_last_message(char* buffer, int size);

#ifdef __cplusplus
}
#endif

#endif
