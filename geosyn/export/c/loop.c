/* loop.c: the exported controller in a closed loop against the robot's MJCF, in MuJoCo.
 *
 * usage: ./loop [model.xml] [duration_s] [push_force_N] [push_start_s] [push_length_s]
 *
 * Each 1 ms tick (the model's time step) does what geosyn.sim.Simulation does:
 * mj_step1, geosyn_controller_compute(t, q, v), torques to the motors (clipped to their
 * ctrlrange), a push on GEOSYN_LOOP_PUSH_BODY at its centre of mass (world +x, y, z
 * direction GEOSYN_LOOP_PUSH_DIR) during [start, start + length), mj_step2. It prints
 * the tracking error q - q_ref over the ticks (RMS over ticks and joints, max) and the
 * time of each compute call (median, p99, max) in microseconds, as "key value" lines.
 * With the MPC it also prints the ticks that solved (solve_*) and the ticks between
 * solves (feedback_*: u + K dx) apart, the solve count, the failed solves and the ticks
 * on a fallback.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <mujoco/mujoco.h>

#include "geosyn_controller.h"
#include "geosyn_controller_ext.h"
#include "loop_config.h"

#define NQ GEOSYN_LOOP_NQ

static double now_us(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return 1e6 * (double)ts.tv_sec + 1e-3 * (double)ts.tv_nsec;
}

static int cmp_double(const void* a, const void* b) {
    double x = *(const double*)a, y = *(const double*)b;
    return (x > y) - (x < y);
}

/* Sorts x (n,) and prints "<name>_median_us", "_p99_us", "_max_us". */
static void print_times(const char* name, double* x, long n) {
    qsort(x, (size_t)n, sizeof(double), cmp_double);
    long p99 = (long)ceil(0.99 * (double)n) - 1;
    printf("%s_median_us %.4f\n", name, n ? x[n / 2] : NAN);
    printf("%s_p99_us %.4f\n", name, n ? x[p99 < 0 ? 0 : p99] : NAN);
    printf("%s_max_us %.4f\n", name, n ? x[n - 1] : NAN);
}

int main(int argc, char** argv) {
    const char* path = argc > 1 ? argv[1] : GEOSYN_LOOP_MODEL;
    double duration = argc > 2 ? atof(argv[2]) : GEOSYN_LOOP_DURATION;
    double force = argc > 3 ? atof(argv[3]) : GEOSYN_LOOP_PUSH_FORCE;
    double push_start = argc > 4 ? atof(argv[4]) : GEOSYN_LOOP_PUSH_START;
    double push_len = argc > 5 ? atof(argv[5]) : GEOSYN_LOOP_PUSH_LENGTH;
    char err[1000] = "";
    mjModel* m = mj_loadXML(path, NULL, err, sizeof(err));
    if (!m) {
        fprintf(stderr, "loop: cannot load %s: %s\n", path, err);
        return 2;
    }
    mjData* d = mj_makeData(m);
    int qadr[NQ], dadr[NQ];
    for (int j = 0; j < NQ; ++j) {
        int jid = mj_name2id(m, mjOBJ_JOINT, geosyn_loop_joints[j]);
        if (jid < 0 || m->nu != NQ) {
            fprintf(stderr, "loop: %s has no joint %s or not %d motors\n", path,
                    geosyn_loop_joints[j], NQ);
            return 2;
        }
        qadr[j] = m->jnt_qposadr[jid];
        dadr[j] = m->jnt_dofadr[jid];
    }
    int body = mj_name2id(m, mjOBJ_BODY, GEOSYN_LOOP_PUSH_BODY);
    geosyn_controller* ctl = geosyn_controller_create();
    if (!ctl || body < 0 || geosyn_controller_nq(ctl) != NQ) {
        fprintf(stderr, "loop: controller or push body %s unavailable\n", GEOSYN_LOOP_PUSH_BODY);
        return 2;
    }
    double dt = m->opt.timestep;
    long n_ticks = lround(duration / dt);
    size_t n_alloc = (size_t)(n_ticks > 0 ? n_ticks : 1);
    double* tick_us = (double*)malloc(sizeof(double) * n_alloc);
    double* solve_us = (double*)malloc(sizeof(double) * n_alloc);
    double* feedback_us = (double*)malloc(sizeof(double) * n_alloc);
    long n_solve = 0, n_feedback = 0, fallback_ticks = 0;
    int info[5] = {0}, solves_before = 0;
    double info_values[2];
    double q[NQ], v[NQ], tau[NQ], qr[NQ], vr[NQ], ar[NQ];
    mj_resetData(m, d);
    for (int j = 0; j < NQ; ++j) d->qpos[qadr[j]] = geosyn_loop_q0[j];
    mj_forward(m, d);
    for (int j = 0; j < NQ; ++j) {
        q[j] = d->qpos[qadr[j]];
        v[j] = d->qvel[dadr[j]];
    }
    geosyn_controller_reset(ctl, q, v);
    double sq = 0.0, max_err = 0.0;
    long done = 0;
    const double eps = 1e-9; /* geosyn.sim.disturbances: a window [start, end) in ticks */
    for (long k = 0; k < n_ticks; ++k) {
        double t = (double)k * dt;
        d->time = t;
        mj_step1(m, d);
        for (int j = 0; j < NQ; ++j) {
            q[j] = d->qpos[qadr[j]];
            v[j] = d->qvel[dadr[j]];
        }
        double c0 = now_us();
        int rc = geosyn_controller_compute(ctl, t, q, v, tau);
        tick_us[k] = now_us() - c0;
        geosyn_controller_mpc_info(ctl, info, info_values);
        if (info[0] > solves_before) solve_us[n_solve++] = tick_us[k];
        else feedback_us[n_feedback++] = tick_us[k];
        solves_before = info[0];
        fallback_ticks += info[4] != 0;
        if (rc != GEOSYN_OK) {
            fprintf(stderr, "loop: compute failed at t=%g: %s\n", t, geosyn_controller_error(rc));
            break;
        }
        mju_zero(d->xfrc_applied, 6 * m->nbody);
        if (push_start - eps <= t && t < push_start + push_len - eps) {
            for (int i = 0; i < 3; ++i)
                d->xfrc_applied[6 * body + i] += force * geosyn_loop_push_dir[i];
        }
        for (int j = 0; j < NQ; ++j) {
            double lo = m->actuator_ctrlrange[2 * j], hi = m->actuator_ctrlrange[2 * j + 1];
            d->ctrl[j] = m->actuator_ctrllimited[j] ? fmin(fmax(tau[j], lo), hi) : tau[j];
        }
        geosyn_controller_sample_reference(ctl, t, qr, vr, ar);
        for (int j = 0; j < NQ; ++j) {
            double e = q[j] - qr[j];
            sq += e * e;
            if (fabs(e) > max_err) max_err = fabs(e);
        }
        done = k + 1;
        mj_step2(m, d);
    }
    printf("ticks %ld\n", done);
    printf("dt_s %.9g\n", dt);
    printf("rms_error_rad %.9g\n", done ? sqrt(sq / ((double)done * NQ)) : NAN);
    printf("max_error_rad %.9g\n", max_err);
    print_times("tick", tick_us, done);
    if (info[0] > 0) {
        printf("solves %d\nfailed_solves %d\nfallback_ticks %ld\n", info[0], info[1],
               fallback_ticks);
        print_times("solve", solve_us, n_solve);
        print_times("feedback", feedback_us, n_feedback);
    }
    free(tick_us);
    free(solve_us);
    free(feedback_us);
    geosyn_controller_destroy(ctl);
    mj_deleteData(d);
    mj_deleteModel(m);
    return done == n_ticks ? 0 : 1;
}
