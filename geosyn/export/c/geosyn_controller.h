/* geosyn_controller.h: the C API of a controller exported by geosyn (geosyn.export).
 *
 * One robot, one controller configuration, compiled in. No CasADi or Python types.
 * Units: joint positions [rad or m], velocities [rad/s or m/s], accelerations
 * [rad/s^2 or m/s^2], time [s], torques [N m or N]. Arrays are joint-major: a
 * reference of n samples is t (n,), q/v/a (n, nq) row-major.
 *
 * Memory: geosyn_controller_create allocates everything once; no other function
 * allocates, blocks or keeps a pointer to its arguments. A controller is not
 * thread-safe: use one per thread.
 *
 * Errors: every int-returning function returns 0 (GEOSYN_OK) or one of the codes below
 * and leaves the controller as it was before the call (still usable);
 * geosyn_controller_error(code) describes a code. geosyn_controller_nq returns
 * -GEOSYN_ERR_NULL for a NULL controller.
 */
#ifndef GEOSYN_CONTROLLER_H
#define GEOSYN_CONTROLLER_H

#ifdef __cplusplus
extern "C" {
#endif

#if defined(__GNUC__)
#define GEOSYN_API __attribute__((visibility("default")))
#else
#define GEOSYN_API
#endif

enum geosyn_controller_status {
    GEOSYN_OK = 0,
    GEOSYN_ERR_NULL = 1,          /* a NULL controller or array */
    GEOSYN_ERR_NONFINITE = 2,     /* NaN or infinite input */
    GEOSYN_ERR_TIME_ORDER = 3,    /* reference times not strictly increasing (or so
                                     close that the interpolant overflows) */
    GEOSYN_ERR_N_SAMPLES = 4,     /* n_samples < 2 or > the compiled maximum */
    GEOSYN_ERR_TORQUE = 5,        /* the control law gave a non-finite torque */
    GEOSYN_ERR_SOLVER = 6         /* reserved: a failed MPC solve falls back (previous plan
                                     or computed torque) as in Python and is counted by
                                     geosyn_controller_mpc_info, not returned */
};

typedef struct geosyn_controller geosyn_controller;

/* Allocates everything once; the built-in reference is set. NULL if out of memory. */
GEOSYN_API geosyn_controller* geosyn_controller_create(void);
/* Frees the controller; NULL is a no-op. */
GEOSYN_API void geosyn_controller_destroy(geosyn_controller* ctl);
/* Joint count nq (= nv). */
GEOSYN_API int geosyn_controller_nq(const geosyn_controller* ctl);
/* Resets internal state (warm starts) at the measured state q (nq,), v (nq,). */
GEOSYN_API int geosyn_controller_reset(geosyn_controller* ctl, const double* q, const double* v);
/* Replaces the reference by n_samples samples t (n,), q, v, a (n, nq), interpolated by a
 * C2 quintic Hermite spline (as geosyn's JointTrajectoryReference with q, v and a); the
 * start is held before t[0], the goal after t[n-1], with zero velocity and acceleration. */
GEOSYN_API int geosyn_controller_set_reference(geosyn_controller* ctl, int n_samples,
                                               const double* t, const double* q,
                                               const double* v, const double* a);
/* Joint torques tau (nq,) for the state (q, v) at time t, clipped to the torque limits.
 * tau is written only on success. */
GEOSYN_API int geosyn_controller_compute(geosyn_controller* ctl, double t, const double* q,
                                         const double* v, double* tau);
/* A static, human-readable description of a status code. */
GEOSYN_API const char* geosyn_controller_error(int code);

#ifdef __cplusplus
}
#endif
#endif /* GEOSYN_CONTROLLER_H */
