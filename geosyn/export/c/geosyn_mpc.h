/* geosyn_mpc.h: the box-DDP MPC driver of an export (internal; not the stable C API).
 * geosyn_controller.c owns one geosyn_mpc when GEOSYN_LAW is GEOSYN_LAW_DDP_MPC. */
#ifndef GEOSYN_MPC_H
#define GEOSYN_MPC_H
#include "geosyn_controller.h"

typedef struct geosyn_mpc geosyn_mpc;

/* Allocates every buffer of the solver once (NULL if out of memory). */
geosyn_mpc* geosyn_mpc_create(void);
void geosyn_mpc_destroy(geosyn_mpc* mpc);
/* Drops the plan: the next compute solves cold (a reset or a new reference). */
void geosyn_mpc_reset(geosyn_mpc* mpc);
/* The torque before clipping, tau_raw (nq,), at (t, q, v): re-solves when t has advanced
 * by dt since the last solve, follows the plan (u + K dx, saturated) in between, falls
 * back to the previous plan or to computed torque on the reference. The reference is
 * read through geosyn_controller_sample_reference(ctl, ...). Never allocates. */
int geosyn_mpc_compute(geosyn_mpc* mpc, geosyn_controller* ctl, double t, const double* q,
                       const double* v, double* tau_raw);
/* Diagnostics (see geosyn_controller_mpc_info in geosyn_controller_ext.h). */
void geosyn_mpc_info(const geosyn_mpc* mpc, int* counts, double* values);
#endif
