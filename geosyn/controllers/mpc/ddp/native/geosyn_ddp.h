/* geosyn_ddp.h: the backward pass of the box-DDP MPC (internal; not the stable C API).
 * The exported driver (geosyn.export's geosyn_mpc.c) owns one geosyn_ddp_work and calls
 * geosyn_ddp_backward and geosyn_ddp_rollout (or their AVX2 builds); geosyn's Python
 * solver calls geosyn_ddp_backward through geosyn_ddp_casadi.c. */
#ifndef GEOSYN_DDP_H
#define GEOSYN_DDP_H
#include "geosyn_controller_config.h"
#ifndef GEOSYN_DDP_SAME_UNIT /* geosyn_ddp_avx2.c holds the generated code itself */
#include "geosyn_mpc_fun.h"
#endif

#define GEOSYN_DDP_NQ GEOSYN_NQ
#define GEOSYN_DDP_NX (2 * GEOSYN_NQ)

/* Every buffer of one backward pass (column-major matrices, as CasADi's, except the
 * row-major RK4 chain: Dx, Du, dx, du, Y, sol, and A, B stored as At, Bt). */
typedef struct {
    double Dx[GEOSYN_DDP_NX * GEOSYN_DDP_NX], Du[GEOSYN_DDP_NX * GEOSYN_DDP_NQ];
    double dx[GEOSYN_DDP_NX * GEOSYN_DDP_NX], du[GEOSYN_DDP_NX * GEOSYN_DDP_NQ];
    double Y[GEOSYN_DDP_NX * GEOSYN_DDP_NX];
    double xk[GEOSYN_DDP_NX], xi[GEOSYN_DDP_NX], xn[GEOSYN_DDP_NX], f[GEOSYN_DDP_NX];
    double M[GEOSYN_DDP_NQ * GEOSYN_DDP_NQ], LM[GEOSYN_DDP_NQ * GEOSYN_DDP_NQ];
    double acc[GEOSYN_DDP_NQ], dR[GEOSYN_DDP_NQ * GEOSYN_DDP_NX];
    double sol[GEOSYN_DDP_NQ * (GEOSYN_DDP_NX + GEOSYN_DDP_NQ)];
    double Vx[GEOSYN_DDP_NX], Vxx[GEOSYN_DDP_NX * GEOSYN_DDP_NX];
    double lx[GEOSYN_DDP_NX], lxx[GEOSYN_DDP_NX * GEOSYN_DDP_NX], lu[GEOSYN_DDP_NQ];
    double luu[GEOSYN_DDP_NQ * GEOSYN_DDP_NQ], lux[GEOSYN_DDP_NQ * GEOSYN_DDP_NX];
    double lo[GEOSYN_DDP_NQ], hi[GEOSYN_DDP_NQ];
    double VA[GEOSYN_DDP_NX * GEOSYN_DDP_NX], VB[GEOSYN_DDP_NX * GEOSYN_DDP_NQ];
    double Qx[GEOSYN_DDP_NX], Qu[GEOSYN_DDP_NQ], Qxx[GEOSYN_DDP_NX * GEOSYN_DDP_NX];
    double Qux[GEOSYN_DDP_NQ * GEOSYN_DDP_NX], Quu[GEOSYN_DDP_NQ * GEOSYN_DDP_NQ];
    double H[GEOSYN_DDP_NQ * GEOSYN_DDP_NQ], L[GEOSYN_DDP_NQ * GEOSYN_DDP_NQ];
    double free[GEOSYN_DDP_NQ], grad[GEOSYN_DDP_NQ], d[GEOSYN_DDP_NQ];
    double best[GEOSYN_DDP_NQ], cand[GEOSYN_DDP_NQ], tmp[GEOSYN_DDP_NQ];
    double rhs[GEOSYN_DDP_NQ * GEOSYN_DDP_NX]; /* row-major: (NQ, NX) */
    double At[GEOSYN_DDP_NX * GEOSYN_DDP_NX], Bt[GEOSYN_DDP_NQ * GEOSYN_DDP_NX]; /* A, B */
    double QuxT[GEOSYN_DDP_NX * GEOSYN_DDP_NQ], hz[GEOSYN_DDP_NQ];
    double L0[GEOSYN_DDP_NQ * GEOSYN_DDP_NQ]; /* factor of the whole control Hessian */
    const casadi_real* arg[GEOSYN_MPC_SZ_ARG];
    casadi_real* res[GEOSYN_MPC_SZ_RES];
    casadi_int iw[GEOSYN_MPC_SZ_IW + 1];
    casadi_real w[GEOSYN_MPC_SZ_W];
} geosyn_ddp_work;

/* One backward pass along (X (2n, N+1), U (n, N)) with the reference (XR, TR) and the
 * parameters P: k (n, N), K (n, 2n N) (block k is K_k), dV (2,). Never allocates. */
typedef void (*geosyn_ddp_backward_fn)(geosyn_ddp_work* w, const double* X, const double* U,
                                       const double* XR, const double* TR, const double* P,
                                       double* k, double* K, double* dV);
/* One closed-loop rollout (geosyn_mpc_rollout) from x0 along (Xb, Ub) with the gains
 * (k, K) and step alpha into (X, U); returns its cost. Never allocates. */
typedef double (*geosyn_ddp_rollout_fn)(geosyn_ddp_work* w, const double* x0,
                                        const double* Xb, const double* Ub, const double* k,
                                        const double* K, double alpha, const double* XR,
                                        const double* TR, const double* P, double* X,
                                        double* U);
void geosyn_ddp_backward(geosyn_ddp_work* w, const double* X, const double* U,
                         const double* XR, const double* TR, const double* P, double* k,
                         double* K, double* dV);
double geosyn_ddp_rollout(geosyn_ddp_work* w, const double* x0, const double* Xb,
                          const double* Ub, const double* k, const double* K, double alpha,
                          const double* XR, const double* TR, const double* P, double* X,
                          double* U);
#if GEOSYN_DDP_AVX2
/* The same two compiled for AVX2 and FMA (geosyn_ddp_avx2.c; the same results up to
 * rounding), called on CPUs that have them. */
void geosyn_ddp_backward_avx2(geosyn_ddp_work* w, const double* X, const double* U,
                              const double* XR, const double* TR, const double* P, double* k,
                              double* K, double* dV);
double geosyn_ddp_rollout_avx2(geosyn_ddp_work* w, const double* x0, const double* Xb,
                               const double* Ub, const double* k, const double* K,
                               double alpha, const double* XR, const double* TR,
                               const double* P, double* X, double* U);
#endif
#endif
