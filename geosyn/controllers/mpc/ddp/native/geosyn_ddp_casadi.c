/* geosyn_ddp_casadi.c: geosyn_ddp_backward behind CasADi's external-function interface,
 * as the function geosyn_ddp_native: (X (2n, N+1), U (n, N), XR (2n, N+1), TR (n, N),
 * P (n_p,)) -> (k (n, N), K (n, 2n N), dV (2,)), the inputs and outputs of
 * geosyn.controllers.mpc.ddp.riccati.backward_graph, all dense. casadi.external loads it
 * like any generated function (geosyn.controllers.mpc.ddp.native.library builds the one
 * translation unit: the generated per-stage functions, this configuration, geosyn_ddp.c
 * and this file). The work struct lives in CasADi's work vector w: no allocation, one
 * work vector per caller (thread-safe as CasADi's own functions are). */
#include "geosyn_ddp.h"

/* the only symbols the library exports (it is built with -fvisibility=hidden, so that
 * two robots' libraries in one process never bind each other's functions) */
#define GEOSYN_DDP_EXPORT __attribute__((visibility("default")))

#define GEOSYN_DDP_WORK_DOUBLES \
    ((sizeof(geosyn_ddp_work) + sizeof(casadi_real) - 1) / sizeof(casadi_real))
#define GEOSYN_DDP_N_K (GEOSYN_DDP_NQ * GEOSYN_MPC_N)
#define GEOSYN_DDP_N_KK (GEOSYN_DDP_NQ * GEOSYN_DDP_NX * GEOSYN_MPC_N)

/* CasADi's compressed form of a dense (rows x cols) pattern: {rows, cols, 1} */
static const casadi_int geosyn_ddp_sp_x[3] = {GEOSYN_DDP_NX, GEOSYN_MPC_N + 1, 1};
static const casadi_int geosyn_ddp_sp_u[3] = {GEOSYN_DDP_NQ, GEOSYN_MPC_N, 1};
static const casadi_int geosyn_ddp_sp_p[3] = {GEOSYN_MPC_NP, 1, 1};
static const casadi_int geosyn_ddp_sp_gains[3] = {GEOSYN_DDP_NQ,
                                                  GEOSYN_DDP_NX * GEOSYN_MPC_N, 1};
static const casadi_int geosyn_ddp_sp_dv[3] = {2, 1, 1};

GEOSYN_DDP_EXPORT int geosyn_ddp_native(const casadi_real** arg, casadi_real** res,
                                           casadi_int* iw, casadi_real* w, int mem) {
    (void)iw;
    (void)mem;
    for (int i = 0; i < 5; ++i)
        if (!arg[i]) return 1; /* a structurally zero input: not a trajectory */
    /* outputs CasADi does not ask for go to scratch space after the work struct */
    casadi_real* scratch = w + GEOSYN_DDP_WORK_DOUBLES;
    casadi_real* k = res[0] ? res[0] : scratch;
    casadi_real* K = res[1] ? res[1] : scratch + GEOSYN_DDP_N_K;
    casadi_real* dV = res[2] ? res[2] : scratch + GEOSYN_DDP_N_K + GEOSYN_DDP_N_KK;
    geosyn_ddp_backward((geosyn_ddp_work*)(void*)w, arg[0], arg[1], arg[2], arg[3], arg[4],
                        k, K, dV);
    return 0;
}

GEOSYN_DDP_EXPORT casadi_int geosyn_ddp_native_n_in(void) { return 5; }
GEOSYN_DDP_EXPORT casadi_int geosyn_ddp_native_n_out(void) { return 3; }

GEOSYN_DDP_EXPORT const char* geosyn_ddp_native_name_in(casadi_int i) {
    static const char* names[5] = {"X", "U", "XR", "TR", "P"};
    return i >= 0 && i < 5 ? names[i] : 0;
}

GEOSYN_DDP_EXPORT const char* geosyn_ddp_native_name_out(casadi_int i) {
    static const char* names[3] = {"k", "K", "dV"};
    return i >= 0 && i < 3 ? names[i] : 0;
}

GEOSYN_DDP_EXPORT const casadi_int* geosyn_ddp_native_sparsity_in(casadi_int i) {
    switch (i) {
        case 0: case 2: return geosyn_ddp_sp_x;
        case 1: case 3: return geosyn_ddp_sp_u;
        case 4: return geosyn_ddp_sp_p;
        default: return 0;
    }
}

GEOSYN_DDP_EXPORT const casadi_int* geosyn_ddp_native_sparsity_out(casadi_int i) {
    switch (i) {
        case 0: return geosyn_ddp_sp_u;
        case 1: return geosyn_ddp_sp_gains;
        case 2: return geosyn_ddp_sp_dv;
        default: return 0;
    }
}

GEOSYN_DDP_EXPORT int geosyn_ddp_native_work(casadi_int* sz_arg, casadi_int* sz_res,
                                                casadi_int* sz_iw, casadi_int* sz_w) {
    if (sz_arg) *sz_arg = 5;
    if (sz_res) *sz_res = 3;
    if (sz_iw) *sz_iw = 0;
    if (sz_w) *sz_w = (casadi_int)GEOSYN_DDP_WORK_DOUBLES + GEOSYN_DDP_N_K + GEOSYN_DDP_N_KK + 2;
    return 0;
}
