/* geosyn_ddp_avx2.c: the MPC's solver code (geosyn_ddp.c and the generated
 * geosyn_mpc_fun.c) compiled a second time, with -mavx2 -mfma -ffp-contract=fast, as one
 * unit whose functions are all file-local but the two entry points
 * geosyn_ddp_backward_avx2 and geosyn_ddp_rollout_avx2. geosyn_mpc.c calls them on CPUs
 * with AVX2 (__builtin_cpu_supports), the baseline build elsewhere: one portable
 * library, the vector instructions where they exist. The fused multiply-adds round
 * differently: the two builds' torques differ by about 1e-13 of the torque limits
 * (both equal the Python MPC's to 1e-9; tests/test_export_mpc.py). */
#ifdef CASADI_SYMBOL_EXPORT
#undef CASADI_SYMBOL_EXPORT
#endif
#define CASADI_SYMBOL_EXPORT static
#define CASADI_CODEGEN_PREFIX 1 /* the generated code's own helpers, renamed */
#define CODEGEN_PREFIX geosyn_mpc_avx2_
#define GEOSYN_DDP_SAME_UNIT 1
#define geosyn_ddp_backward geosyn_ddp_backward_avx2
#define geosyn_ddp_rollout geosyn_ddp_rollout_avx2
#include "geosyn_mpc_fun.c"
#include "geosyn_ddp.c"
