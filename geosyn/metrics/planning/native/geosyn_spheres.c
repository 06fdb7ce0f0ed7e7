/* Collision spheres of a serial or branched robot against obstacles, in C.
 *
 * The planner's sampling check (`geosyn.metrics.planning.sphere_native`): forward
 * kinematics of the robot's revolute and prismatic joints (the tree of Pinocchio's model:
 * parent, placement in the parent, axis, configuration index), the world centres of two
 * sets of spheres (the obstacle set and the self-collision set, each on a joint or on the
 * world), and
 *   - the smallest signed distance sphere - obstacle (exact formulas of
 *     `geosyn.world.distance` for spheres, boxes, capsules, cylinders and half-spaces);
 *   - per self-collision link pair, the smallest distance between its spheres;
 *   - validity: clearance >= margin and every pair at or above its floor (lowered near
 *     a query's ends to their own pair distances, ramping back up with the distance
 *     from them in joint space, as the margin).
 * Robot-independent: one library for every robot (the robot is data, set at creation).
 * No allocation after the set-up calls; not thread-safe per handle (one work area).
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define GS_API __attribute__((visibility("default")))
#define GS_OBSTACLE 16 /* numbers per obstacle (layout in geosyn_spheres_set_obstacles) */

typedef struct {
    int n, *joint;
    double *centre, *radius, *world; /* world: (n, 3) work */
    /* the spheres grouped by joint: members order[start[g] .. start[g + 1] - 1] of group
     * g, bounded by the ball (bound[4 g .. 4 g + 2] in the joint's frame, radius
     * bound[4 g + 3]); group[i] is sphere i's group; gworld: (groups, 3) work */
    int groups, *gjoint, *order, *gstart, *group;
    double *bound, *gworld;
} gs_spheres;

typedef struct {
    int nq, nj;
    int *parent, *kind, *iq;
    double *axis, *place; /* (nj, 3); (nj, 12): R row-major, then p */
    double *R, *p;        /* work: (nj, 9), (nj, 3) world placements */
    gs_spheres obs, own;
    int n_sphere_pairs, n_pairs;
    int *first, *second, *start; /* sphere pairs; (n_pairs + 1) starts */
    double *floor;
    int n_obstacles, *okind;
    double *opar;
    /* a query's n_ends (0-2) ends: at q, the margin in force is min(margin, end_clear[e]
     * + slope |q - ends[e]|) and pair i's floor min(floor[i], end_floor[e n_pairs + i]
     * + floor_slope |q - ends[e]|) over the ends */
    int n_ends;
    double ends[2 * 64], end_clear[2], slope, *end_floor, floor_slope;
    /* local raises: within |q - raise_at[r]| < raise_radius[r], pair raise_pair[r]'s floor
     * is at least raise_floor[r] (before the ends' lowering); raised: (n_pairs,) work */
    int n_raises, *raise_pair;
    double *raise_at, *raise_radius, *raise_floor, *raised;
} gs_model;

static void *copy(const void *src, size_t bytes) {
    void *dst = malloc(bytes ? bytes : 1);
    if (dst && bytes) memcpy(dst, src, bytes);
    return dst;
}

GS_API void *geosyn_spheres_create(int nq, int nj, const int *parent, const int *kind,
                                   const int *iq, const double *axis, const double *place) {
    gs_model *m = calloc(1, sizeof(gs_model));
    if (!m) return NULL;
    m->nq = nq;
    m->nj = nj;
    m->parent = copy(parent, sizeof(int) * nj);
    m->kind = copy(kind, sizeof(int) * nj);
    m->iq = copy(iq, sizeof(int) * nj);
    m->axis = copy(axis, sizeof(double) * 3 * nj);
    m->place = copy(place, sizeof(double) * 12 * nj);
    m->R = malloc(sizeof(double) * 9 * (nj ? nj : 1));
    m->p = malloc(sizeof(double) * 3 * (nj ? nj : 1));
    return m;
}

static void free_spheres(gs_spheres *s) {
    free(s->joint);
    free(s->centre);
    free(s->radius);
    free(s->world);
    free(s->gjoint); free(s->order); free(s->gstart); free(s->group);
    free(s->bound); free(s->gworld);
    memset(s, 0, sizeof(*s));
}

GS_API void geosyn_spheres_free(void *handle) {
    gs_model *m = handle;
    if (!m) return;
    free(m->parent); free(m->kind); free(m->iq); free(m->axis); free(m->place);
    free(m->R); free(m->p);
    free_spheres(&m->obs);
    free_spheres(&m->own);
    free(m->first); free(m->second); free(m->start); free(m->floor); free(m->end_floor);
    free(m->okind); free(m->opar);
    free(m->raise_pair); free(m->raise_at); free(m->raise_radius); free(m->raise_floor);
    free(m->raised);
    free(m);
}

/* which = 0: the obstacle set; 1: the self-collision set. joint -1: the world. */
GS_API int geosyn_spheres_set_spheres(void *handle, int which, int n, const int *joint,
                                      const double *centre, const double *radius) {
    gs_model *m = handle;
    gs_spheres *s = which ? &m->own : &m->obs;
    free_spheres(s);
    s->n = n;
    s->joint = copy(joint, sizeof(int) * n);
    s->centre = copy(centre, sizeof(double) * 3 * n);
    s->radius = copy(radius, sizeof(double) * n);
    s->world = malloc(sizeof(double) * 3 * (n ? n : 1));
    size_t m1 = (size_t)(n ? n : 1);
    s->gjoint = malloc(sizeof(int) * m1);
    s->order = malloc(sizeof(int) * m1);
    s->gstart = malloc(sizeof(int) * (m1 + 1));
    s->group = malloc(sizeof(int) * m1);
    s->bound = calloc(4 * m1, sizeof(double));
    s->gworld = malloc(sizeof(double) * 3 * m1);
    if (!(s->joint && s->centre && s->radius && s->world && s->gjoint && s->order &&
          s->gstart && s->group && s->bound && s->gworld))
        return -1;
    s->groups = 0;
    for (int i = 0; i < n; ++i) { /* groups in order of first appearance */
        int g = 0;
        while (g < s->groups && s->gjoint[g] != joint[i]) ++g;
        if (g == s->groups) s->gjoint[s->groups++] = joint[i];
        s->group[i] = g;
    }
    int at = 0;
    for (int g = 0; g < s->groups; ++g) {
        s->gstart[g] = at;
        double *b = s->bound + 4 * g, count = 0.0;
        for (int i = 0; i < n; ++i)
            if (s->group[i] == g) {
                s->order[at++] = i;
                for (int a = 0; a < 3; ++a) b[a] += centre[3 * i + a];
                count += 1.0;
            }
        for (int a = 0; a < 3; ++a) b[a] /= count;
        for (int i = 0; i < n; ++i)
            if (s->group[i] == g) {
                const double *c = centre + 3 * i;
                double dx = c[0] - b[0], dy = c[1] - b[1], dz = c[2] - b[2];
                double r = sqrt(dx * dx + dy * dy + dz * dz) + radius[i];
                if (r > b[3]) b[3] = r;
            }
        b[3] *= 1.0 + 1e-12; /* round-off: the ball holds its spheres */
    }
    s->gstart[s->groups] = at;
    return 0;
}

/* Sphere pairs (first[k], second[k]) of the self set; pair i owns sphere pairs
 * start[i] .. start[i + 1] - 1; floor: (n_pairs,) lowest accepted distance [m]. */
GS_API int geosyn_spheres_set_pairs(void *handle, int n_sphere_pairs, const int *first,
                                    const int *second, int n_pairs, const int *start,
                                    const double *floor) {
    gs_model *m = handle;
    free(m->first); free(m->second); free(m->start); free(m->floor);
    free(m->end_floor);
    m->n_sphere_pairs = n_sphere_pairs;
    m->n_pairs = n_pairs;
    m->first = copy(first, sizeof(int) * n_sphere_pairs);
    m->second = copy(second, sizeof(int) * n_sphere_pairs);
    m->start = copy(start, sizeof(int) * (n_pairs + 1));
    m->floor = copy(floor, sizeof(double) * n_pairs);
    m->end_floor = calloc(2 * (size_t)n_pairs + 1, sizeof(double));
    m->n_ends = 0; /* the ends' pair distances are the old pairs' */
    m->n_raises = 0; /* and so are the raises' pairs */
    free(m->raised);
    m->raised = malloc(sizeof(double) * (n_pairs ? n_pairs : 1));
    return (m->first && m->second && m->start && m->floor && m->end_floor && m->raised) ? 0 : -1;
}

/* Obstacles, GS_OBSTACLE numbers each, by kind:
 *   0 sphere:    centre (3), ..., radius at [15]
 *   1 box:       centre (3), R (9, row-major, world from box), half extents (3)
 *   2 capsule:   p0 (3), p1 (3), ..., radius at [15]
 *   3 cylinder:  centre (3), R (9), radius [12], half length [13] (along local z)
 *   4 halfspace: normal (3), offset [3] (the obstacle is normal . x <= offset) */
GS_API int geosyn_spheres_set_obstacles(void *handle, int n, const int *kind, const double *par) {
    gs_model *m = handle;
    free(m->okind); free(m->opar);
    m->n_obstacles = n;
    m->okind = copy(kind, sizeof(int) * n);
    m->opar = copy(par, sizeof(double) * GS_OBSTACLE * n);
    return (m->okind && m->opar) ? 0 : -1;
}

/* A query's ends (see gs_model): n_ends (0-2) configurations (n_ends, nq) with their
 * clearances clear (n_ends,) [m] and the margin's slope [m/rad]; the pairs' floors away
 * from them floor (n_pairs,) [m], their pair distances end_floor (n_ends, n_pairs) [m]
 * and the floors' slope floor_slope [m/rad]. */
GS_API int geosyn_spheres_set_ends(void *handle, int n_ends, const double *ends,
                                   const double *clear, double slope, const double *floor,
                                   const double *end_floor, double floor_slope) {
    gs_model *m = handle;
    if (n_ends < 0 || n_ends > 2 || m->nq > 64) return -1;
    m->n_ends = n_ends;
    memcpy(m->ends, ends, sizeof(double) * m->nq * n_ends);
    memcpy(m->end_clear, clear, sizeof(double) * n_ends);
    m->slope = slope;
    if (m->n_pairs) {
        memcpy(m->floor, floor, sizeof(double) * m->n_pairs);
        memcpy(m->end_floor, end_floor, sizeof(double) * m->n_pairs * n_ends);
    }
    m->floor_slope = floor_slope;
    return 0;
}

/* n local raises (see gs_model): pair (n,), at (n, nq) [rad], radius (n,) [rad], floor
 * (n,) [m]. Replaces the earlier ones; needs the pairs set (set_pairs clears them). */
GS_API int geosyn_spheres_set_raises(void *handle, int n, const int *pair, const double *at,
                                     const double *radius, const double *floor) {
    gs_model *m = handle;
    if (n < 0 || !m->raised) return -1;
    for (int r = 0; r < n; ++r)
        if (pair[r] < 0 || pair[r] >= m->n_pairs) return -1;
    free(m->raise_pair); free(m->raise_at); free(m->raise_radius); free(m->raise_floor);
    m->raise_pair = copy(pair, sizeof(int) * n);
    m->raise_at = copy(at, sizeof(double) * m->nq * n);
    m->raise_radius = copy(radius, sizeof(double) * n);
    m->raise_floor = copy(floor, sizeof(double) * n);
    int ok = m->raise_pair && m->raise_at && m->raise_radius && m->raise_floor;
    m->n_raises = ok ? n : 0;
    return ok ? 0 : -1;
}

static void kinematics(gs_model *m, const double *q) {
    for (int j = 0; j < m->nj; ++j) {
        const double *P = m->place + 12 * j, *u = m->axis + 3 * j;
        double L[9], lp[3]; /* placement times the joint's own motion, in the parent */
        double x = q[m->iq[j]];
        if (m->kind[j] == 0) { /* revolute: Rodrigues */
            double c = cos(x), s = sin(x), t = 1.0 - c;
            double J[9] = {t * u[0] * u[0] + c,        t * u[0] * u[1] - s * u[2], t * u[0] * u[2] + s * u[1],
                           t * u[0] * u[1] + s * u[2], t * u[1] * u[1] + c,        t * u[1] * u[2] - s * u[0],
                           t * u[0] * u[2] - s * u[1], t * u[1] * u[2] + s * u[0], t * u[2] * u[2] + c};
            for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b)
                    L[3 * a + b] = P[3 * a] * J[b] + P[3 * a + 1] * J[3 + b] + P[3 * a + 2] * J[6 + b];
            lp[0] = P[9]; lp[1] = P[10]; lp[2] = P[11];
        } else { /* prismatic */
            memcpy(L, P, sizeof(double) * 9);
            for (int a = 0; a < 3; ++a)
                lp[a] = P[9 + a] + x * (P[3 * a] * u[0] + P[3 * a + 1] * u[1] + P[3 * a + 2] * u[2]);
        }
        double *R = m->R + 9 * j, *p = m->p + 3 * j;
        int par = m->parent[j];
        if (par < 0) {
            memcpy(R, L, sizeof(double) * 9);
            memcpy(p, lp, sizeof(double) * 3);
        } else {
            const double *A = m->R + 9 * par, *ap = m->p + 3 * par;
            for (int a = 0; a < 3; ++a) {
                for (int b = 0; b < 3; ++b)
                    R[3 * a + b] = A[3 * a] * L[b] + A[3 * a + 1] * L[3 + b] + A[3 * a + 2] * L[6 + b];
                p[a] = ap[a] + A[3 * a] * lp[0] + A[3 * a + 1] * lp[1] + A[3 * a + 2] * lp[2];
            }
        }
    }
}

/* w = the point c of joint j's frame in the world (j -1: the world itself). */
static void to_world(const gs_model *m, int j, const double *c, double *w) {
    if (j < 0) {
        w[0] = c[0]; w[1] = c[1]; w[2] = c[2];
        return;
    }
    const double *R = m->R + 9 * j, *p = m->p + 3 * j;
    for (int a = 0; a < 3; ++a) w[a] = p[a] + R[3 * a] * c[0] + R[3 * a + 1] * c[1] + R[3 * a + 2] * c[2];
}

static void place_spheres(const gs_model *m, gs_spheres *s) {
    for (int i = 0; i < s->n; ++i) to_world(m, s->joint[i], s->centre + 3 * i, s->world + 3 * i);
}

static void place_bounds(const gs_model *m, gs_spheres *s) {
    for (int g = 0; g < s->groups; ++g) to_world(m, s->gjoint[g], s->bound + 4 * g, s->gworld + 3 * g);
}

/* e = d (a point less the capsule's first end) less its nearest point of the segment. */
static void capsule_offset(const double *o, const double *d, double *e) {
    double ab[3] = {o[3] - o[0], o[4] - o[1], o[5] - o[2]};
    double den = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2], t = 0.0;
    if (den > 0.0) {
        t = (d[0] * ab[0] + d[1] * ab[1] + d[2] * ab[2]) / den;
        t = t < 0.0 ? 0.0 : (t > 1.0 ? 1.0 : t);
    }
    for (int a = 0; a < 3; ++a) e[a] = d[a] - t * ab[a];
}

static double distance(int kind, const double *o, const double *x) {
    double d[3] = {x[0] - o[0], x[1] - o[1], x[2] - o[2]};
    switch (kind) {
    case 0:
        return sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) - o[15];
    case 1: {
        double out = 0.0, in = -INFINITY;
        for (int b = 0; b < 3; ++b) {
            double l = fabs(d[0] * o[3 + b] + d[1] * o[6 + b] + d[2] * o[9 + b]) - o[12 + b];
            if (l > 0.0) out += l * l;
            if (l > in) in = l;
        }
        return sqrt(out) + (in < 0.0 ? in : 0.0);
    }
    case 2: {
        double e[3];
        capsule_offset(o, d, e);
        return sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]) - o[15];
    }
    case 3: {
        double l[3];
        for (int b = 0; b < 3; ++b) l[b] = d[0] * o[3 + b] + d[1] * o[6 + b] + d[2] * o[9 + b];
        double u0 = hypot(l[0], l[1]) - o[12], u1 = fabs(l[2]) - o[13];
        double a0 = u0 > 0.0 ? u0 : 0.0, a1 = u1 > 0.0 ? u1 : 0.0, mx = u0 > u1 ? u0 : u1;
        return sqrt(a0 * a0 + a1 * a1) + (mx < 0.0 ? mx : 0.0);
    }
    default:
        return x[0] * o[0] + x[1] * o[1] + x[2] * o[2] - o[3];
    }
}

/* The smallest sphere-obstacle clearance, or (stop finite) the first one found below
 * stop; who (NULL: not asked) gets the (sphere, obstacle) of the smallest. A group whose
 * ball is at least the best found (or stop) away is skipped: signed distances are
 * 1-Lipschitz, so the ball's clearance bounds its spheres'. Needs the balls placed
 * (place_bounds); computes the world centres of the spheres it visits. */
static double clearance(gs_model *m, double stop, int *who) {
    double best = INFINITY;
    gs_spheres *s = &m->obs;
    for (int g = 0; g < s->groups; ++g) {
        const double *bw = s->gworld + 3 * g, *bl = s->bound + 4 * g;
        for (int k = 0; k < m->n_obstacles; ++k) {
            const double *o = m->opar + GS_OBSTACLE * k;
            double lim = stop > -INFINITY ? stop : best;
            if (distance(m->okind[k], o, bw) - bl[3] >= lim) continue;
            for (int at = s->gstart[g]; at < s->gstart[g + 1]; ++at) {
                int i = s->order[at];
                double w[3];
                to_world(m, s->gjoint[g], s->centre + 3 * i, w);
                double v = distance(m->okind[k], o, w) - s->radius[i];
                if (v < best) {
                    best = v;
                    if (who) { who[0] = i; who[1] = k; }
                }
            }
            if (best < stop) return best;
        }
    }
    return best;
}

static double pair_distance(const gs_model *m, int pair) {
    const gs_spheres *s = &m->own;
    double best = INFINITY;
    for (int k = m->start[pair]; k < m->start[pair + 1]; ++k) {
        const double *a = s->world + 3 * m->first[k], *b = s->world + 3 * m->second[k];
        double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
        double v = sqrt(dx * dx + dy * dy + dz * dz) - s->radius[m->first[k]] - s->radius[m->second[k]];
        if (v < best) best = v;
    }
    return best;
}

/* Whether pair `pair` keeps its floor (lowered near the ends: `away` (n_ends,)
 * the joint-space distances from them): its joints' balls first (a lower bound of
 * every sphere distance), then its spheres, squared distances. Needs both placed. */
static int pair_ok(const gs_model *m, int pair, const double *away, const double *raised) {
    const gs_spheres *s = &m->own;
    double floor = m->floor[pair];
    if (raised && raised[pair] > floor) floor = raised[pair];
    for (int e = 0; e < m->n_ends; ++e) {
        double v = m->end_floor[(size_t)m->n_pairs * e + pair] + m->floor_slope * away[e];
        if (v < floor) floor = v;
    }
    int k0 = m->start[pair], k1 = m->start[pair + 1];
    if (k0 == k1) return 1;
    int ga = s->group[m->first[k0]], gb = s->group[m->second[k0]];
    const double *a = s->gworld + 3 * ga, *b = s->gworld + 3 * gb;
    double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    double lim = s->bound[4 * ga + 3] + s->bound[4 * gb + 3] + floor;
    if (lim <= 0.0 || dx * dx + dy * dy + dz * dz >= lim * lim) return 1;
    for (int k = k0; k < k1; ++k) {
        int i = m->first[k], j = m->second[k];
        const double *x = s->world + 3 * i, *y = s->world + 3 * j;
        double ex = x[0] - y[0], ey = x[1] - y[1], ez = x[2] - y[2];
        double t = s->radius[i] + s->radius[j] + floor, d2 = ex * ex + ey * ey + ez * ez;
        /* near the floor, the distance as pair_distance computes it (the floors come
         * from it: a configuration at its own floor stays valid) */
        if (t > 0.0 && d2 < t * t * (1.0 + 1e-9) &&
            sqrt(d2) - s->radius[i] - s->radius[j] < floor)
            return 0;
    }
    return 1;
}

/* out[k]: the smallest sphere-obstacle clearance at configuration k of Q (K, nq) [m]. */
GS_API void geosyn_spheres_clearances(void *handle, const double *Q, int K, double *out) {
    gs_model *m = handle;
    for (int k = 0; k < K; ++k) {
        kinematics(m, Q + (size_t)m->nq * k);
        place_bounds(m, &m->obs);
        out[k] = clearance(m, -INFINITY, NULL);
    }
}

/* g (3,): the gradient of distance(kind, o, x) in x (zero where it has none: at a
 * sphere's or capsule's centre line, a box's or cylinder's centre). */
static void distance_gradient(int kind, const double *o, const double *x, double *g) {
    double d[3] = {x[0] - o[0], x[1] - o[1], x[2] - o[2]}, n;
    g[0] = g[1] = g[2] = 0.0;
    switch (kind) {
    case 0:
        n = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if (n > 0.0)
            for (int a = 0; a < 3; ++a) g[a] = d[a] / n;
        return;
    case 1: { /* axis b of the box: (o[3 + b], o[6 + b], o[9 + b]) */
        double l[3], sg[3], out = 0.0, in = -INFINITY, w[3] = {0.0, 0.0, 0.0};
        int deepest = 0;
        for (int b = 0; b < 3; ++b) {
            double t = d[0] * o[3 + b] + d[1] * o[6 + b] + d[2] * o[9 + b];
            sg[b] = t < 0.0 ? -1.0 : 1.0;
            l[b] = fabs(t) - o[12 + b];
            if (l[b] > 0.0) out += l[b] * l[b];
            if (l[b] > in) { in = l[b]; deepest = b; }
        }
        if (out > 0.0) /* outside: towards the nearest point */
            for (int b = 0; b < 3; ++b) w[b] = l[b] > 0.0 ? sg[b] * l[b] / sqrt(out) : 0.0;
        else /* inside: out through the nearest face */
            w[deepest] = sg[deepest];
        for (int a = 0; a < 3; ++a) g[a] = o[3 * a + 3] * w[0] + o[3 * a + 4] * w[1] + o[3 * a + 5] * w[2];
        return;
    }
    case 2: {
        double e[3];
        capsule_offset(o, d, e);
        n = sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
        if (n > 0.0)
            for (int a = 0; a < 3; ++a) g[a] = e[a] / n;
        return;
    }
    case 3: { /* in the cylinder's frame: radial (l0, l1), axial l2 */
        double l[3], w[3] = {0.0, 0.0, 0.0};
        for (int b = 0; b < 3; ++b) l[b] = d[0] * o[3 + b] + d[1] * o[6 + b] + d[2] * o[9 + b];
        double rho = hypot(l[0], l[1]), u0 = rho - o[12], u1 = fabs(l[2]) - o[13];
        double a0 = u0 > 0.0 ? u0 : 0.0, a1 = u1 > 0.0 ? u1 : 0.0, out = sqrt(a0 * a0 + a1 * a1);
        double radial = 0.0, axial = 0.0, sz = l[2] < 0.0 ? -1.0 : 1.0;
        if (out > 0.0) {
            radial = a0 / out;
            axial = a1 / out;
        } else if (u0 > u1) {
            radial = 1.0;
        } else {
            axial = 1.0;
        }
        if (rho > 0.0) { w[0] = radial * l[0] / rho; w[1] = radial * l[1] / rho; }
        w[2] = axial * sz;
        for (int a = 0; a < 3; ++a) g[a] = o[3 * a + 3] * w[0] + o[3 * a + 4] * w[1] + o[3 * a + 5] * w[2];
        return;
    }
    default:
        g[0] = o[0]; g[1] = o[1]; g[2] = o[2];
        return;
    }
}

/* out[k] as geosyn_spheres_clearances and grad (K, nq): its gradient [m/rad], that of the
 * nearest (sphere, obstacle) pair: the distance's gradient at the sphere's centre x
 * times dx/dq (a revolute joint's world axis w at o_j: w x (x - o_j); a prismatic
 * one's: w), summed over the joints from the sphere's up to the root. Zero without a
 * pair (inf) or for a sphere fixed to the world. At a kink of the minimum (two pairs
 * equally near), one side's gradient. */
GS_API void geosyn_spheres_clearance_gradients(void *handle, const double *Q, int K,
                                               double *out, double *grad) {
    gs_model *m = handle;
    gs_spheres *s = &m->obs;
    for (int k = 0; k < K; ++k) {
        double *g = grad + (size_t)m->nq * k, n[3], x[3];
        int who[2] = {-1, -1};
        kinematics(m, Q + (size_t)m->nq * k);
        place_bounds(m, s);
        out[k] = clearance(m, -INFINITY, who);
        memset(g, 0, sizeof(double) * m->nq);
        if (who[0] < 0) continue;
        int j = s->joint[who[0]];
        to_world(m, j, s->centre + 3 * who[0], x);
        distance_gradient(m->okind[who[1]], m->opar + GS_OBSTACLE * who[1], x, n);
        for (; j >= 0; j = m->parent[j]) {
            const double *R = m->R + 9 * j, *p = m->p + 3 * j, *u = m->axis + 3 * j;
            double w[3];
            for (int a = 0; a < 3; ++a) w[a] = R[3 * a] * u[0] + R[3 * a + 1] * u[1] + R[3 * a + 2] * u[2];
            if (m->kind[j] == 0) { /* n . (w x r) = (r x n) . w */
                double r[3] = {x[0] - p[0], x[1] - p[1], x[2] - p[2]};
                g[m->iq[j]] += (r[1] * n[2] - r[2] * n[1]) * w[0] + (r[2] * n[0] - r[0] * n[2]) * w[1] +
                               (r[0] * n[1] - r[1] * n[0]) * w[2];
            } else {
                g[m->iq[j]] += n[0] * w[0] + n[1] * w[1] + n[2] * w[2];
            }
        }
    }
}

/* out (K, S, O): the clearance of every sphere of the obstacle set to every obstacle [m]
 * (signed distance of its centre minus its radius). */
GS_API void geosyn_spheres_obstacle_distances(void *handle, const double *Q, int K, double *out) {
    gs_model *m = handle;
    gs_spheres *s = &m->obs;
    int O = m->n_obstacles;
    for (int k = 0; k < K; ++k) {
        kinematics(m, Q + (size_t)m->nq * k);
        place_spheres(m, s);
        for (int i = 0; i < s->n; ++i)
            for (int o = 0; o < O; ++o)
                out[((size_t)k * s->n + i) * O + o] =
                    distance(m->okind[o], m->opar + GS_OBSTACLE * o, s->world + 3 * i) - s->radius[i];
    }
}

/* out (K, G, O): per group g of spheres (group[i] in [0, G) for sphere i of the obstacle
 * set, -1: in none), the smallest clearance of its spheres to every obstacle [m] (+inf
 * for a group without spheres). */
GS_API void geosyn_spheres_group_distances(void *handle, const double *Q, int K,
                                           const int *group, int G, double *out) {
    gs_model *m = handle;
    gs_spheres *s = &m->obs;
    int O = m->n_obstacles;
    for (size_t x = 0; x < (size_t)K * G * O; ++x) out[x] = INFINITY;
    for (int k = 0; k < K; ++k) {
        kinematics(m, Q + (size_t)m->nq * k);
        place_spheres(m, s);
        for (int i = 0; i < s->n; ++i) {
            if (group[i] < 0) continue;
            double *row = out + ((size_t)k * G + group[i]) * O;
            for (int o = 0; o < O; ++o) {
                double d = distance(m->okind[o], m->opar + GS_OBSTACLE * o, s->world + 3 * i) - s->radius[i];
                if (d < row[o]) row[o] = d;
            }
        }
    }
}

/* R (K, J, 9) row-major world rotations and p (K, J, 3) world positions of the J joints
 * at each configuration of Q (K, nq). */
GS_API void geosyn_spheres_frames(void *handle, const double *Q, int K, double *R, double *p) {
    gs_model *m = handle;
    for (int k = 0; k < K; ++k) {
        kinematics(m, Q + (size_t)m->nq * k);
        memcpy(R + (size_t)9 * m->nj * k, m->R, sizeof(double) * 9 * m->nj);
        memcpy(p + (size_t)3 * m->nj * k, m->p, sizeof(double) * 3 * m->nj);
    }
}

/* out (K, n_pairs): the smallest sphere distance of each self pair [m]. */
GS_API void geosyn_spheres_self_clearances(void *handle, const double *Q, int K, double *out) {
    gs_model *m = handle;
    for (int k = 0; k < K; ++k) {
        kinematics(m, Q + (size_t)m->nq * k);
        place_spheres(m, &m->own);
        for (int i = 0; i < m->n_pairs; ++i) out[(size_t)m->n_pairs * k + i] = pair_distance(m, i);
    }
}

/* Whether configuration q keeps clearance >= margin and (self) every pair its floor. */
static int config_valid(gs_model *m, const double *q, double margin, int self) {
    double away[2]; /* the joint-space distances from the ends, for both ramps */
    for (int e = 0; e < m->n_ends; ++e) {
        const double *x = m->ends + m->nq * e;
        double d2 = 0.0;
        for (int i = 0; i < m->nq; ++i) d2 += (q[i] - x[i]) * (q[i] - x[i]);
        away[e] = sqrt(d2);
        double v = m->end_clear[e] + m->slope * away[e];
        if (v < margin) margin = v;
    }
    kinematics(m, q);
    if (m->n_obstacles && m->obs.n) {
        place_bounds(m, &m->obs);
        if (clearance(m, margin, NULL) < margin) return 0;
    }
    if (self && m->n_pairs) {
        place_spheres(m, &m->own);
        place_bounds(m, &m->own);
        const double *raised = NULL;
        if (m->n_raises) { /* the local raises in force at q */
            for (int i = 0; i < m->n_pairs; ++i) m->raised[i] = -INFINITY;
            for (int r = 0; r < m->n_raises; ++r) {
                const double *x = m->raise_at + (size_t)m->nq * r;
                double d2 = 0.0, R = m->raise_radius[r];
                for (int i = 0; i < m->nq; ++i) d2 += (q[i] - x[i]) * (q[i] - x[i]);
                int k = m->raise_pair[r];
                if (d2 < R * R && m->raise_floor[r] > m->raised[k]) m->raised[k] = m->raise_floor[r];
            }
            raised = m->raised;
        }
        for (int i = 0; i < m->n_pairs; ++i)
            if (!pair_ok(m, i, away, raised)) return 0;
    }
    return 1;
}

/* out[k] = 1 where configuration k is valid (config_valid); returns the number of valid
 * configurations. stop_at_invalid: return at the first invalid one (the rest of out
 * left as it was). */
GS_API int geosyn_spheres_valid(void *handle, const double *Q, int K, double margin, int self,
                                int stop_at_invalid, unsigned char *out) {
    gs_model *m = handle;
    int count = 0;
    for (int k = 0; k < K; ++k) {
        int ok = config_valid(m, Q + (size_t)m->nq * k, margin, self);
        out[k] = (unsigned char)ok;
        count += ok;
        if (!ok && stop_at_invalid) return count;
    }
    return count;
}

/* Whether the straight segment a -> b is valid at the points a + (i / k) (b - a),
 * i = 1 .. k, k = max(1, ceil(|b - a| / resolution)) (a itself is not checked). */
static int segment_valid(gs_model *m, const double *a, const double *b, double resolution,
                         double margin, int self, double *q) {
    int n = m->nq;
    double d2 = 0.0;
    for (int i = 0; i < n; ++i) d2 += (b[i] - a[i]) * (b[i] - a[i]);
    int k = (int)ceil(sqrt(d2) / resolution);
    k = k < 1 ? 1 : k;
    for (int s = 1; s <= k; ++s) {
        double u = (double)s / k;
        for (int i = 0; i < n; ++i) q[i] = a[i] + u * (b[i] - a[i]);
        if (!config_valid(m, q, margin, self)) return 0;
    }
    return 1;
}

GS_API int geosyn_spheres_segment_valid(void *handle, const double *a, const double *b,
                                        double resolution, double margin, int self) {
    gs_model *m = handle;
    double q[64];
    if (m->nq > 64) return -1;
    return segment_valid(m, a, b, resolution, margin, self, q);
}

/* Whether every segment X[t] -> X[t + 1] of the path X (T, nq) is valid (segment_valid),
 * stopping at the first invalid one; X[0] itself is not checked. */
GS_API int geosyn_spheres_path_valid(void *handle, const double *X, int T, double resolution,
                                     double margin, int self) {
    gs_model *m = handle;
    double q[64];
    if (m->nq > 64) return -1;
    for (int t = 0; t + 1 < T; ++t) {
        const double *a = X + (size_t)m->nq * t;
        if (!segment_valid(m, a, a + m->nq, resolution, margin, self, q)) return 0;
    }
    return 1;
}

static double seconds_now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static double uniform(uint64_t *s) { /* xorshift128+, in [0, 1) */
    uint64_t x = s[0], y = s[1];
    s[0] = y;
    x ^= x << 23;
    s[1] = x ^ y ^ (x >> 17) ^ (y >> 26);
    return (double)((s[1] + y) >> 11) * (1.0 / 9007199254740992.0);
}

typedef struct {
    double *q, *radius;
    int *parent, *size;
} gs_tree;

/* Extend tree t towards target by at most step: the new node's index, or -1 (the
 * segment from the nearest node is invalid, or the tree is full), or -2 (dynamic domain
 * on, dd[0] > 0: the target lies beyond the nearest node's radius, nothing checked);
 * *reached: the new node is the target. With the domain on, a node's radius (r, per
 * node; infinite when new) becomes dd[0] at its first failed extension, then shrinks by
 * the factor 1 - dd[2] at each failure (to at least dd[1]) and grows by 1 + dd[2] at
 * each success (Yershova et al. 2005's dynamic-domain RRT). */
static int extend(gs_model *m, gs_tree *t, const double *target, double step, double resolution,
                  double margin, int self, int max_nodes, int *reached, double *work,
                  const double *dd) {
    int n = m->nq, best = 0;
    double bd = INFINITY;
    for (int i = 0; i < *t->size; ++i) {
        const double *x = t->q + (size_t)n * i;
        double d = 0.0;
        for (int a = 0; a < n && d < bd; ++a) d += (x[a] - target[a]) * (x[a] - target[a]);
        if (d < bd) bd = d, best = i;
    }
    if (*t->size >= max_nodes) return -1;
    const double *near = t->q + (size_t)n * best;
    double dist = sqrt(bd), *fresh = t->q + (size_t)n * *t->size;
    double *r = t->radius + best;
    const int domain = dd && dd[0] > 0.0;
    if (domain && dist > *r) return -2;
    *reached = dist <= step;
    for (int a = 0; a < n; ++a)
        fresh[a] = *reached ? target[a] : near[a] + (target[a] - near[a]) * (step / dist);
    if (!segment_valid(m, near, fresh, resolution, margin, self, work)) {
        if (domain) *r = isinf(*r) ? dd[0] : fmax(*r * (1.0 - dd[2]), dd[1]);
        return -1;
    }
    if (domain && !isinf(*r)) *r *= 1.0 + dd[2];
    t->parent[*t->size] = best;
    t->radius[*t->size] = INFINITY;
    return (*t->size)++;
}

/* RRT-Connect (Kuffner & LaValle) on trees 0 (rooted at the start) and 1 (the goal),
 * resumable: the trees (q (max_nodes, n), parent (max_nodes,), radius (max_nodes,),
 * size[2]), whose turn it is (*turn: the tree that grows towards the next sample) and
 * the sampler's state (rng[2]) live in the caller's arrays. Grows them towards uniform
 * samples of the box [lo, hi], or, with probability near, of the box [near_lo, near_hi]
 * (near 0: no draw for it), for at most `seconds`; the sampled tree's extension has a
 * dynamic domain when dd[0] > 0 (`extend`); balance: the turn passes to the other tree
 * unless that one has at least twice the nodes. Returns 1 when they connect (ends[0] in
 * tree 0, ends[1] in tree 1 are the same configuration), 0 when the time is spent, -1
 * when a tree is full. */
GS_API int geosyn_spheres_rrt_connect(void *handle, const double *lo, const double *hi,
                                      const double *near_lo, const double *near_hi, double near,
                                      double step, double resolution, double margin, int self,
                                      double *q0, int *p0, double *r0, double *q1, int *p1,
                                      double *r1, int *size, int max_nodes, int *turn,
                                      uint64_t *rng, double seconds, const double *dd,
                                      int balance, int *ends) {
    gs_model *m = handle;
    int n = m->nq;
    double sample[64], work[64];
    if (n > 64) return -2;
    gs_tree trees[2] = {{q0, r0, p0, size}, {q1, r1, p1, size + 1}};
    double end = seconds_now() + seconds;
    while (seconds_now() < end) {
        gs_tree *a = &trees[*turn], *b = &trees[1 - *turn];
        if (*a->size >= max_nodes || *b->size >= max_nodes) return -1;
        const double *a_lo = lo, *a_hi = hi;
        if (near > 0.0 && uniform(rng) < near) {
            a_lo = near_lo;
            a_hi = near_hi;
        }
        for (int i = 0; i < n; ++i) sample[i] = a_lo[i] + uniform(rng) * (a_hi[i] - a_lo[i]);
        int reached = 0, j = extend(m, a, sample, step, resolution, margin, self, max_nodes,
                                    &reached, work, dd);
        if (j >= 0) {
            const double *target = a->q + (size_t)n * j;
            for (;;) {
                int k = extend(m, b, target, step, resolution, margin, self, max_nodes,
                               &reached, work, NULL);
                if (k < 0) break;
                if (reached) {
                    ends[*turn] = j;
                    ends[1 - *turn] = k;
                    return 1;
                }
                if (seconds_now() >= end) break;
            }
        }
        if (!balance || *b->size < 2 * *a->size) *turn = 1 - *turn;
    }
    return 0;
}
