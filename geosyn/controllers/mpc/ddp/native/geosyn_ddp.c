/* geosyn_ddp.c: the backward pass of the box-DDP MPC (hand-written), used by geosyn's
 * Python solver (geosyn_ddp_casadi.c, geosyn.controllers.mpc.ddp.native) and by the
 * exported C MPC (geosyn.export copies this file).
 *
 * The same mathematics as geosyn's Python solver (geosyn.controllers.mpc.ddp: riccati.py
 * backward_graph, parts.py riccati_step, box_qp.py; geosyn.controllers.mpc.ocp.rk4
 * rk4_linearisation), written as loops over small dense matrices instead of CasADi's
 * unrolled scalar code: the generated functions (geosyn_mpc_fun.c) give, per call, the
 * mass matrix and the torque left for acceleration (geosyn_mpc_dyn) and the Jacobian of
 * the inverse dynamics (geosyn_mpc_drnea), from which the ODE's value and Jacobian at
 * one point follow with one Cholesky factor of M; a stage's Gauss-Newton cost
 * derivatives and torque box (geosyn_mpc_stage) and the terminal cost's derivatives
 * (geosyn_mpc_terminal); this file chains RK4's Jacobian through them and runs the
 * Riccati recursion with the projected-Newton box QP. The results equal the Python
 * solver's up to rounding (the sums run in another order).
 *
 * Matrices are column-major (element (r, c) of an R x C matrix at [c R + r]).
 */
#include <math.h>
#include <string.h>

#include "geosyn_ddp.h"

#define NQ GEOSYN_DDP_NQ
#define NX GEOSYN_DDP_NX
#define N GEOSYN_MPC_N

/* ---- small SPD solves (geosyn.controllers.mpc.ocp.linalg) --------------------------- */

static void cholesky(const double* H, double* L) {
    memset(L, 0, sizeof(double) * NQ * NQ);
    for (int j = 0; j < NQ; ++j) {
        double s = H[j * NQ + j];
        for (int k = 0; k < j; ++k) s -= L[k * NQ + j] * L[k * NQ + j];
        L[j * NQ + j] = sqrt(s);
        for (int i = j + 1; i < NQ; ++i) {
            double t = H[j * NQ + i];
            for (int k = 0; k < j; ++k) t -= L[k * NQ + i] * L[k * NQ + j];
            L[j * NQ + i] = t / L[j * NQ + j];
        }
    }
}

/* y (NQ,) <- (L L^T)^-1 y */
static void cholesky_solve(const double* L, double* y) {
    for (int i = 0; i < NQ; ++i) {
        double s = y[i];
        for (int k = 0; k < i; ++k) s -= L[k * NQ + i] * y[k];
        y[i] = s / L[i * NQ + i];
    }
    for (int i = NQ - 1; i >= 0; --i) {
        double s = y[i];
        for (int k = i + 1; k < NQ; ++k) s -= L[i * NQ + k] * y[k];
        y[i] = s / L[i * NQ + i];
    }
}

/* Y (NQ x width, row-major: the right-hand sides side by side) <- (L L^T)^-1 Y */
static void cholesky_solve_rows(const double* restrict L, double* restrict Y, int width) {
    for (int i = 0; i < NQ; ++i) {
        double* yi = Y + i * width;
        for (int k = 0; k < i; ++k) {
            const double l = L[k * NQ + i];
            const double* yk = Y + k * width;
            for (int c = 0; c < width; ++c) yi[c] -= l * yk[c];
        }
        const double d = L[i * NQ + i];
        for (int c = 0; c < width; ++c) yi[c] /= d;
    }
    for (int i = NQ - 1; i >= 0; --i) {
        double* yi = Y + i * width;
        for (int k = i + 1; k < NQ; ++k) {
            const double l = L[i * NQ + k];
            const double* yk = Y + k * width;
            for (int c = 0; c < width; ++c) yi[c] -= l * yk[c];
        }
        const double d = L[i * NQ + i];
        for (int c = 0; c < width; ++c) yi[c] /= d;
    }
}

/* ---- the RK4 step's Jacobians (rk4_linearisation) ---------------------------------- */

#define ODE_W (NX + NQ) /* right-hand sides of the ODE's solve: -dR, then I */

/* out (NX x m) = A Y + (add_minv ? [0; Minv] : 0), row-major like Y, with the ODE's
 * Jacobian A = [[0, I], [S]] (d(q')/d(q, v) = [0, I], d(v')/d(q, v) = S); the rows of S
 * and Minv are the rows of w->sol. */
static void ode_times(const geosyn_ddp_work* restrict w, const double* restrict Y, int m,
                      int add_minv, double* restrict out) {
    memcpy(out, Y + NQ * m, sizeof(double) * (size_t)(NQ * m));
    for (int i = 0; i < NQ; ++i) {
        double* o = out + (NQ + i) * m;
        const double* srow = w->sol + i * ODE_W;
        for (int c = 0; c < m; ++c) o[c] = add_minv ? srow[NX + c] : 0.0;
        for (int j = 0; j < NX; ++j) {
            const double sj = srow[j];
            const double* y = Y + j * m;
            for (int c = 0; c < m; ++c) o[c] += sj * y[c];
        }
    }
}

/* The ODE at (x, u): f = (v, a) with a = M^-1 r (the ABA's value); the rows of w->sol:
 * S = d a / d(q, v) = -M^-1 dR at that a, then Minv = d a / du. */
static void ode(geosyn_ddp_work* w, const double* x, const double* u) {
    w->arg[0] = x; w->arg[1] = u;
    w->res[0] = w->M; w->res[1] = w->acc;
    geosyn_mpc_dyn(w->arg, w->res, w->iw, w->w, 0);
    cholesky(w->M, w->LM);
    cholesky_solve(w->LM, w->acc);
    memcpy(w->f, x + NQ, sizeof(double) * NQ);
    memcpy(w->f + NQ, w->acc, sizeof(double) * NQ);
    w->arg[0] = x; w->arg[1] = w->acc;
    w->res[0] = w->dR;
    geosyn_mpc_drnea(w->arg, w->res, w->iw, w->w, 0);
    for (int i = 0; i < NQ; ++i) {
        double* row = w->sol + i * ODE_W;
        for (int c = 0; c < NX; ++c) row[c] = -w->dR[c * NQ + i];
        for (int c = 0; c < NQ; ++c) row[NX + c] = i == c ? 1.0 : 0.0;
    }
    cholesky_solve_rows(w->LM, w->sol, ODE_W);
}

/* w->At = A = dF/dx (NX x NX), w->Bt = B = dF/du (NX x NQ) of the RK4 step from x with
 * u, both row-major (so that, read column-major, they are A^T and B^T). */
static void linearise(geosyn_ddp_work* w, const double* x, const double* u) {
    const double hs = GEOSYN_MPC_DT / GEOSYN_MPC_RK4_STEPS;
    const double cs[4] = {0.0, 0.5 * hs, 0.5 * hs, hs};
    const double ws[4] = {hs / 6.0, hs / 3.0, hs / 3.0, hs / 6.0};
    double* Dx = w->At; /* accumulated in place */
    double* Du = w->Bt;
    memset(Dx, 0, sizeof w->At);
    for (int i = 0; i < NX; ++i) Dx[i * NX + i] = 1.0;
    memset(Du, 0, sizeof w->Bt);
    memcpy(w->xk, x, sizeof w->xk);
    for (int step = 0; step < GEOSYN_MPC_RK4_STEPS; ++step) {
        memcpy(w->xn, w->xk, sizeof w->xn);
        memcpy(w->Dx, Dx, sizeof w->Dx); /* Dx, Du of the step's start */
        memcpy(w->Du, Du, sizeof w->Du);
        memset(w->dx, 0, sizeof w->dx);
        memset(w->du, 0, sizeof w->du);
        for (int s = 0; s < 4; ++s) {
            const double c = cs[s], wt = ws[s];
            if (s == 0) {
                ode(w, w->xk, u);
            } else {
                for (int i = 0; i < NX; ++i) w->xi[i] = w->xk[i] + c * w->f[i];
                ode(w, w->xi, u);
            }
            /* dx <- A (Dx + c dx), du <- A (Du + c du) + B */
            for (int i = 0; i < NX * NX; ++i) w->Y[i] = w->Dx[i] + c * w->dx[i];
            ode_times(w, w->Y, NX, 0, w->dx);
            for (int i = 0; i < NX * NQ; ++i) w->Y[i] = w->Du[i] + c * w->du[i];
            ode_times(w, w->Y, NQ, 1, w->du);
            for (int i = 0; i < NX; ++i) w->xn[i] += wt * w->f[i];
            for (int i = 0; i < NX * NX; ++i) Dx[i] += wt * w->dx[i];
            for (int i = 0; i < NX * NQ; ++i) Du[i] += wt * w->du[i];
        }
        memcpy(w->xk, w->xn, sizeof w->xk);
    }
}

/* ---- the box QP (box_qp.py: projected Newton, BOX_ITERATIONS steps) ----------------- */

/* hz <- H z (column axpys: no long dependency chain) */
static void sym_times(const double* restrict H, const double* restrict z, double* restrict hz) {
    for (int r = 0; r < NQ; ++r) hz[r] = 0.0;
    for (int c = 0; c < NQ; ++c) {
        const double zc = z[c];
        const double* h = H + c * NQ;
        for (int r = 0; r < NQ; ++r) hz[r] += h[r] * zc;
    }
}

static double qp_value(geosyn_ddp_work* w, const double* H, const double* g, const double* z) {
    sym_times(H, z, w->hz);
    double v = 0.0;
    for (int r = 0; r < NQ; ++r) v += z[r] * (0.5 * w->hz[r] + g[r]);
    return v;
}

static void clip(const double* z, const double* lo, const double* hi, double* out) {
    for (int i = 0; i < NQ; ++i) out[i] = fmin(fmax(z[i], lo[i]), hi[i]);
}

/* free[i] = 0 for a control at a bound with the gradient g + H k pushing outwards;
 * returns the number of clamped controls. */
static int free_mask(geosyn_ddp_work* w, const double* H, const double* g, const double* k,
                     const double* lo, const double* hi) {
    sym_times(H, k, w->grad);
    int clamped_count = 0;
    for (int r = 0; r < NQ; ++r) {
        const double gr = g[r] + w->grad[r];
        w->grad[r] = gr;
        int clamped = (k[r] <= lo[r] && gr > 0) || (k[r] >= hi[r] && gr < 0);
        w->free[r] = clamped ? 0.0 : 1.0;
        clamped_count += clamped;
    }
    return clamped_count;
}

/* L <- Cholesky factor of H on the free controls (identity on the clamped ones); with
 * every control free that is H itself, whose factor L0 is known. */
static void masked_factor(geosyn_ddp_work* w, const double* H, int clamped) {
    if (!clamped) {
        memcpy(w->L, w->L0, sizeof w->L);
        return;
    }
    for (int c = 0; c < NQ; ++c)
        for (int r = 0; r < NQ; ++r)
            w->H[c * NQ + r] = H[c * NQ + r] * (w->free[r] * w->free[c]) +
                               (r == c ? 1.0 - w->free[r] : 0.0);
    cholesky(w->H, w->L);
}

/* k <- argmin 0.5 k^T H k + g^T k on lo <= k <= hi; w->free, w->L: its free set and the
 * factor of its masked Hessian. An iteration that keeps k is a fixed point (the next
 * ones would repeat it exactly), so the loop stops there; an unconstrained minimiser
 * inside the box is returned as it is. */
static void box_qp(geosyn_ddp_work* w, const double* H, const double* g, const double* lo,
                   const double* hi, double* k) {
    static const double steps[4] = {1.0, 0.5, 0.25, 0.1};
    double trace = 0.0;
    for (int i = 0; i < NQ; ++i) trace += H[i * NQ + i];
    cholesky(H, w->L0);
    for (int i = 0; i < NQ; ++i) w->tmp[i] = g[i];
    cholesky_solve(w->L0, w->tmp);
    int inside = 1;
    for (int i = 0; i < NQ; ++i) {
        k[i] = -w->tmp[i];
        inside = inside && lo[i] < k[i] && k[i] < hi[i];
    }
    if (inside) { /* the unconstrained minimiser: every control free (the projected
                     Newton steps would only move it by rounding) */
        for (int i = 0; i < NQ; ++i) w->free[i] = 1.0;
        memcpy(w->L, w->L0, sizeof w->L);
        return;
    }
    clip(k, lo, hi, k);
    for (int it = 0; it < GEOSYN_MPC_BOX_ITERATIONS; ++it) {
        masked_factor(w, H, free_mask(w, H, g, k, lo, hi));
        for (int i = 0; i < NQ; ++i) w->d[i] = w->free[i] * w->grad[i];
        cholesky_solve(w->L, w->d);
        double best = qp_value(w, H, g, k);
        int moved = 0;
        for (int s = 0; s < 5; ++s) {
            for (int i = 0; i < NQ; ++i)
                w->tmp[i] = s < 4 ? k[i] + steps[s] * -w->d[i] : k[i] - w->grad[i] / trace;
            clip(w->tmp, lo, hi, w->cand);
            double value = qp_value(w, H, g, w->cand);
            if (value < best) {
                best = value;
                memcpy(w->best, w->cand, sizeof w->best);
                moved = 1;
            }
        }
        if (!moved) break;
        memcpy(k, w->best, sizeof w->best);
    }
    masked_factor(w, H, free_mask(w, H, g, k, lo, hi));
}

/* ---- one Riccati step (riccati_step) --------------------------------------------------- */

/* out (rows x cols, column-major) += Mt V: Mt (rows x NX) column-major, V (NX x cols)
 * with element (j, c) at V[j * sj + c * sc]. */
static void add_product(const double* restrict Mt, int rows, const double* restrict V, int sj,
                        int sc, int cols, double* restrict out) {
    for (int c = 0; c < cols; ++c) {
        double* o = out + c * rows;
        for (int j = 0; j < NX; ++j) {
            const double vj = V[j * sj + c * sc];
            const double* m = Mt + j * rows;
            for (int r = 0; r < rows; ++r) o[r] += m[r] * vj;
        }
    }
}

static void riccati(geosyn_ddp_work* w, const double* x, const double* u, const double* xr,
                    const double* tr, const double* P, double* k, double* K, double* dV) {
    w->arg[0] = x; w->arg[1] = u; w->arg[2] = xr; w->arg[3] = tr; w->arg[4] = P;
    w->res[0] = w->lx; w->res[1] = w->lxx; w->res[2] = w->lu; w->res[3] = w->luu;
    w->res[4] = w->lux; w->res[5] = w->lo; w->res[6] = w->hi;
    geosyn_mpc_stage(w->arg, w->res, w->iw, w->w, 0);
    /* w->At, w->Bt: A and B row-major, i.e. A^T and B^T column-major */
    memset(w->VA, 0, sizeof w->VA); /* VA = Vxx A, VB = Vxx B (Vxx symmetric: Vxx^T) */
    add_product(w->Vxx, NX, w->At, NX, 1, NX, w->VA);
    memset(w->VB, 0, sizeof w->VB);
    add_product(w->Vxx, NX, w->Bt, NQ, 1, NQ, w->VB);
    memcpy(w->Qx, w->lx, sizeof w->Qx); /* Qx = lx + A^T Vx, Qu = lu + B^T Vx */
    add_product(w->At, NX, w->Vx, 1, 0, 1, w->Qx);
    memcpy(w->Qu, w->lu, sizeof w->Qu);
    add_product(w->Bt, NQ, w->Vx, 1, 0, 1, w->Qu);
    /* Qxx = lxx + A^T Vxx A: symmetric, its upper half (and the diagonal) only */
    for (int c = 0; c < NX; ++c) {
        double* o = w->Qxx + c * NX;
        const double* va = w->VA + c * NX;
        for (int r = 0; r <= c; ++r) o[r] = w->lxx[c * NX + r];
        for (int j = 0; j < NX; ++j) {
            const double vj = va[j];
            const double* m = w->At + j * NX;
            for (int r = 0; r <= c; ++r) o[r] += m[r] * vj;
        }
    }
    memcpy(w->Qux, w->lux, sizeof w->Qux); /* Qux = lux + B^T VA */
    add_product(w->Bt, NQ, w->VA, 1, NX, NX, w->Qux);
    memcpy(w->H, w->luu, sizeof w->H); /* Quu = sym(luu + reg I + B^T VB) */
    for (int i = 0; i < NQ; ++i) w->H[i * NQ + i] += P[GEOSYN_MPC_REG_INDEX];
    add_product(w->Bt, NQ, w->VB, 1, NX, NQ, w->H);
    for (int c = 0; c < NQ; ++c)
        for (int r = 0; r < NQ; ++r)
            w->Quu[c * NQ + r] = 0.5 * (w->H[c * NQ + r] + w->H[r * NQ + c]);
    for (int i = 0; i < NQ; ++i) {
        w->lo[i] -= u[i];
        w->hi[i] -= u[i];
    }
    box_qp(w, w->Quu, w->Qu, w->lo, w->hi, k);
    /* K = -H_free^-1 (free * Qux), solved with the NX right-hand sides side by side */
    for (int i = 0; i < NQ; ++i)
        for (int c = 0; c < NX; ++c) w->rhs[i * NX + c] = w->free[i] * w->Qux[c * NQ + i];
    cholesky_solve_rows(w->L, w->rhs, NX);
    for (int i = 0; i < NQ; ++i)
        for (int c = 0; c < NX; ++c) K[c * NQ + i] = -w->rhs[i * NX + c];
    /* Vx = Qx + K^T (Quu k + Qu) + Qux^T k; Vxx = sym(Qxx + Qux^T K) */
    sym_times(w->Quu, k, w->hz);
    double dv0 = 0.0, dv1 = 0.0;
    for (int r = 0; r < NQ; ++r) {
        w->tmp[r] = w->hz[r] + w->Qu[r];
        dv0 += k[r] * w->Qu[r];
        dv1 += k[r] * w->hz[r];
    }
    dV[0] += dv0;
    dV[1] += 0.5 * dv1;
    for (int r = 0; r < NX; ++r) {
        const double* Kr = K + r * NQ;
        const double* Qr = w->Qux + r * NQ;
        double s = 0.0, t = 0.0;
        for (int i = 0; i < NQ; ++i) {
            s += Kr[i] * w->tmp[i];
            t += Qr[i] * k[i];
        }
        w->Vx[r] = w->Qx[r] + s + t;
    }
    for (int c = 0; c < NX; ++c) /* QuxT: the rows of Qux as columns */
        for (int i = 0; i < NQ; ++i) w->QuxT[i * NX + c] = w->Qux[c * NQ + i];
    /* Qux^T K = -Qux_f^T H_f^-1 Qux_f is symmetric too: upper halves, mirrored */
    for (int c = 0; c < NX; ++c) {
        double* o = w->Vxx + c * NX;
        for (int r = 0; r <= c; ++r) o[r] = w->Qxx[c * NX + r];
        for (int i = 0; i < NQ; ++i) {
            const double kc = K[c * NQ + i];
            const double* q = w->QuxT + i * NX;
            for (int r = 0; r <= c; ++r) o[r] += q[r] * kc;
        }
    }
    for (int c = 0; c < NX; ++c)
        for (int r = c + 1; r < NX; ++r) w->Vxx[c * NX + r] = w->Vxx[r * NX + c];
}

void geosyn_ddp_backward(geosyn_ddp_work* w, const double* X, const double* U,
                         const double* XR, const double* TR, const double* P, double* k,
                         double* K, double* dV) {
    w->arg[0] = X + N * NX; w->arg[1] = XR + N * NX; w->arg[2] = P;
    w->res[0] = w->Vx; w->res[1] = w->Vxx;
    geosyn_mpc_terminal(w->arg, w->res, w->iw, w->w, 0);
    dV[0] = 0.0;
    dV[1] = 0.0;
    for (int s = N - 1; s >= 0; --s) {
        linearise(w, X + s * NX, U + s * NQ);
        riccati(w, X + s * NX, U + s * NQ, XR + s * NX, TR + s * NQ, P, k + s * NQ,
                K + (size_t)s * NQ * NX, dV);
    }
}

#ifndef GEOSYN_DDP_BACKWARD_ONLY /* geosyn's Python solver rolls out in its own code */
double geosyn_ddp_rollout(geosyn_ddp_work* w, const double* x0, const double* Xb,
                          const double* Ub, const double* k, const double* K, double alpha,
                          const double* XR, const double* TR, const double* P, double* X,
                          double* U) {
    double cost = NAN;
    w->arg[0] = x0; w->arg[1] = Xb; w->arg[2] = Ub; w->arg[3] = k; w->arg[4] = K;
    w->arg[5] = &alpha; w->arg[6] = XR; w->arg[7] = TR; w->arg[8] = P;
    w->res[0] = X; w->res[1] = U; w->res[2] = &cost;
    geosyn_mpc_rollout(w->arg, w->res, w->iw, w->w, 0);
    return cost;
}
#endif
