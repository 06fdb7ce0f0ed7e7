/* geosyn_controller_ext.h: helpers of the programs shipped with an export (loop.c).
 * Not part of the stable C API (geosyn_controller.h). */
#ifndef GEOSYN_CONTROLLER_EXT_H
#define GEOSYN_CONTROLLER_EXT_H
#include "geosyn_controller.h"
#ifdef __cplusplus
extern "C" {
#endif
/* The reference the controller tracks at time t: q, v, a (nq,) each. */
GEOSYN_API int geosyn_controller_sample_reference(geosyn_controller* ctl, double t, double* q,
                                                  double* v, double* a);
/* The MPC's diagnostics (zeros and NaN for other laws): counts[5] = solves, failed
 * solves, iterations of the last solve, its status (1 warm step, 2 cold converged,
 * 3 failed, 4 skipped: measured state outside the limits' margin), the fallback of
 * the last compute (0 none, 1 previous plan, 2 computed torque on the reference);
 * values[2] = cost of the last successful solve, time of the plan [s]. */
GEOSYN_API int geosyn_controller_mpc_info(const geosyn_controller* ctl, int* counts,
                                          double* values);
#ifdef __cplusplus
}
#endif
#endif
