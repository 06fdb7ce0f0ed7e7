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
#ifdef __cplusplus
}
#endif
#endif
