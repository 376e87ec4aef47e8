/* The resting pose of a rigid tracked base lowered onto a heightmap: mmstab's C kernel.
 *
 * The same algorithm as the NumPy path (mmstab/terrain/rest/numpy_path.py; poses.py explains
 * it: lower, pick the supporting triangle by a 2-D linear programme, Newton step on it,
 * repeat), written per pose: a coarse stage on a sparse subset of the candidates, a fine
 * stage on each pose's highest candidates checked against all of them, and a re-solve on
 * all of them where the check fails. Every function mirrors the NumPy function of the same
 * name, operation for operation, so both paths give the same rests to rounding (tested).
 *
 * No static state; the work arrays are allocated once per call (mmstab_rest, mmstab_polish).
 */
#include <math.h>
#include <stdlib.h>

static const double PI = 3.14159265358979323846;

typedef struct {
    const double *elev; /* (ny, nx) row-major elevation [m], NaN = unknown */
    long ny, nx;
    double ox, oy; /* G (x, y) of the centre of cell [0, 0] [m] */
    double res;    /* [m/cell] */
} Map;

typedef struct {
    int max_iterations;
    double tol_step, max_step, max_tilt, approach, approach_factor;
    double coarse_tol, final_step, active_tol;
    long active_candidates;
} Settings;

typedef struct {
    double R[3][3], dRr[3][3], dRp[3][3];
} Rot;

/* Bilinear height (and slopes if hx != NULL) at G (x, y); 0 when off the map or unknown. */
static int sample(const Map *m, double x, double y, double *h, double *hx, double *hy)
{
    const double inv = 1.0 / m->res, eps = 1e-9;
    double u = (x - m->ox) * inv, v = (y - m->oy) * inv;
    int ok = u >= -eps && u <= (double)(m->nx - 1) + eps && v >= -eps
             && v <= (double)(m->ny - 1) + eps;
    /* clamped in floating point first: the cell index is always inside the map */
    double uc = u > 0.0 ? u : 0.0, vc = v > 0.0 ? v : 0.0;
    if (!(uc <= (double)(m->nx - 2))) uc = (double)(m->nx - 2);
    if (!(vc <= (double)(m->ny - 2))) vc = (double)(m->ny - 2);
    long ix = (long)uc, iy = (long)vc;
    double fx = u - (double)ix, fy = v - (double)iy;
    const double *e = m->elev + iy * m->nx + ix;
    double h00 = e[0], h10 = e[1], h01 = e[m->nx], h11 = e[m->nx + 1];
    double ax = h10 - h00, bx = h11 - h01;
    double low = h00 + fx * ax;
    double dy = h01 + fx * bx - low;
    *h = low + fy * dy;
    if (hx) {
        *hx = (ax + fy * (bx - ax)) * inv;
        *hy = dy * inv;
    }
    return ok && isfinite(*h);
}

static void matmul3(double A[3][3], double B[3][3], double C[3][3])
{
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            C[i][j] = A[i][0] * B[0][j] + A[i][1] * B[1][j] + A[i][2] * B[2][j];
}

/* G_R_B = Rz(yaw) Ry(-pitch) Rx(roll) and its derivatives by roll and pitch. */
static void rotations(double yaw, double roll, double pitch, Rot *out)
{
    double cy = cos(yaw), sy = sin(yaw), cr = cos(roll), sr = sin(roll);
    double cp = cos(pitch), sp = sin(pitch);
    double Rz[3][3] = {{cy, -sy, 0}, {sy, cy, 0}, {0, 0, 1}};
    double Ry[3][3] = {{cp, 0, -sp}, {0, 1, 0}, {sp, 0, cp}};
    double Rx[3][3] = {{1, 0, 0}, {0, cr, -sr}, {0, sr, cr}};
    double dRy[3][3] = {{-sp, 0, -cp}, {0, 0, 0}, {cp, 0, -sp}};
    double dRx[3][3] = {{0, 0, 0}, {0, -sr, -cr}, {0, cr, -sr}};
    double RzRy[3][3], RzdRy[3][3];
    matmul3(Rz, Ry, RzRy);
    matmul3(RzRy, Rx, out->R);
    matmul3(RzRy, dRx, out->dRr);
    matmul3(Rz, dRy, RzdRy);
    matmul3(RzdRy, Rx, out->dRp);
}

static double dot3(const double *a, const double *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* Lifts f (Ks) and lever arms J (Ks, 2) of the candidates idx; 0 if any is off the map. */
static int lift(const Map *m, const double *c, const long *idx, long Ks, const Rot *r,
                double px, double py, double *f, double *J)
{
    int ok = 1;
    for (long s = 0; s < Ks; ++s) {
        const double *ck = c + 3 * idx[s];
        double h;
        ok &= sample(m, px + dot3(r->R[0], ck), py + dot3(r->R[1], ck), &h, NULL, NULL);
        f[s] = h - dot3(r->R[2], ck);
        J[2 * s] = -dot3(r->dRr[2], ck);
        J[2 * s + 1] = -dot3(r->dRp[2], ck);
    }
    return ok;
}

/* Only the lifts (as lift), of the candidates idx or, with idx NULL, all Ks of them. */
static int heights(const Map *m, const double *c, const long *idx, long Ks, const Rot *r,
                   double px, double py, double *f)
{
    int ok = 1;
    for (long s = 0; s < Ks; ++s) {
        const double *ck = c + 3 * (idx ? idx[s] : s);
        double h;
        ok &= sample(m, px + dot3(r->R[0], ck), py + dot3(r->R[1], ck), &h, NULL, NULL);
        f[s] = h - dot3(r->R[2], ck);
    }
    return ok;
}

/* ---- the supporting triangle (support_lp.py), one problem ---------------------------- */

typedef struct {
    const double *J, *f; /* (Ks, 2), (Ks) */
    long Ks;
    double art[3][2], big;
} LP;

static const double *point(const LP *lp, long k)
{
    return k < lp->Ks ? lp->J + 2 * k : lp->art[k - lp->Ks];
}

static double value(const LP *lp, long k) { return k < lp->Ks ? lp->f[k] : -lp->big; }

static double den_of(const double *a, const double *b, const double *c, double ab[2], double ac[2])
{
    ab[0] = b[0] - a[0], ab[1] = b[1] - a[1];
    ac[0] = c[0] - a[0], ac[1] = c[1] - a[1];
    double den = ab[0] * ac[1] - ab[1] * ac[0];
    return fabs(den) > 1e-300 ? den : 1e-300;
}

/* barycentric coordinates of x in the triangle tri */
static void bary(const LP *lp, const long tri[3], const double x[2], double lam[3])
{
    const double *a = point(lp, tri[0]);
    double ab[2], ac[2];
    double den = den_of(a, point(lp, tri[1]), point(lp, tri[2]), ab, ac);
    double ax0 = x[0] - a[0], ax1 = x[1] - a[1];
    double lb = (ax0 * ac[1] - ax1 * ac[0]) / den;
    double lc = (ab[0] * ax1 - ab[1] * ax0) / den;
    lam[0] = 1.0 - lb - lc, lam[1] = lb, lam[2] = lc;
}

/* t and d of the plane value(J) = t - d . J through the triangle's lifted points */
static void plane(const LP *lp, const long tri[3], double *t, double d[2])
{
    const double *a = point(lp, tri[0]);
    double ab[2], ac[2];
    double den = den_of(a, point(lp, tri[1]), point(lp, tri[2]), ab, ac);
    double F0 = value(lp, tri[0]);
    double fb = value(lp, tri[1]) - F0, fc = value(lp, tri[2]) - F0;
    double gx = (fb * ac[1] - fc * ab[1]) / den;
    double gy = (-fb * ac[0] + fc * ab[0]) / den;
    *t = F0 - gx * a[0] - gy * a[1];
    d[0] = -gx, d[1] = -gy;
}

/* min t - q.d s.t. t >= f_k + J_k.d; returns bounded (no artificial vertex left) */
static int support_lp(const double *J, const double *f, long Ks, const double q[2],
                      const long *warm, const long corners[4], long basis[3], double d[2])
{
    LP lp = {J, f, Ks, {{0}}, 0};
    double fmax = -INFINITY, fmin = INFINITY, jmax = 0.0;
    for (long k = 0; k < Ks; ++k) {
        fmax = f[k] > fmax ? f[k] : fmax;
        fmin = f[k] < fmin ? f[k] : fmin;
        double a = fabs(J[2 * k]), b = fabs(J[2 * k + 1]);
        jmax = a > jmax ? a : jmax;
        jmax = b > jmax ? b : jmax;
    }
    double qa = fabs(q[0]) > fabs(q[1]) ? fabs(q[0]) : fabs(q[1]);
    double scale = jmax + qa + 1.0;
    for (int j = 0; j < 3; ++j) {
        double ang = PI / 2 + 2 * PI / 3 * j;
        lp.art[j][0] = q[0] + 100.0 * scale * cos(ang);
        lp.art[j][1] = q[1] + 100.0 * scale * sin(ang);
    }
    lp.big = 1e6 * (fmax - fmin + 1.0);
    long b[3] = {Ks, Ks + 1, Ks + 2};
    /* the warm triangle, then the footprint corners' triangles, if one holds q */
    long tries[5][3];
    int ntries = 0;
    if (warm) tries[ntries][0] = warm[0], tries[ntries][1] = warm[1], tries[ntries++][2] = warm[2];
    for (int j = 0; j < 4; ++j) {
        int w = 0;
        for (int i = 0; i < 4; ++i)
            if (i != j) tries[ntries][w++] = corners[i];
        ++ntries;
    }
    for (int i = 0; i < ntries; ++i) {
        double lam[3];
        bary(&lp, tries[i], q, lam);
        if (lam[0] >= -1e-12 && lam[1] >= -1e-12 && lam[2] >= -1e-12) {
            b[0] = tries[i][0], b[1] = tries[i][1], b[2] = tries[i][2];
            break;
        }
    }
    double tol = 1e-12 * ((fmax > -fmin ? fmax : -fmin) + 1.0);
    double t;
    for (long it = 0; it < 4 * Ks + 12; ++it) {
        plane(&lp, b, &t, d);
        long e = 0;
        double best = -INFINITY;
        for (long k = 0; k < Ks; ++k) {
            double viol = f[k] + (J[2 * k] * d[0] + J[2 * k + 1] * d[1]) - t;
            if (viol > best || isnan(viol)) {
                best = viol, e = k;
                if (isnan(viol)) break; /* NumPy's argmax stops at the first NaN */
            }
        }
        if (!(best > tol)) break;
        double lam[3], mu[3];
        bary(&lp, b, q, lam);
        bary(&lp, b, J + 2 * e, mu);
        long leave = 0;
        double rmin = INFINITY;
        for (int j = 0; j < 3; ++j) {
            double ratio = mu[j] > 1e-12 ? lam[j] / mu[j] : INFINITY;
            if (j == 0 || ratio < rmin) rmin = ratio, leave = j;
        }
        b[leave] = e;
    }
    basis[0] = b[0], basis[1] = b[1], basis[2] = b[2];
    return b[0] < Ks && b[1] < Ks && b[2] < Ks;
}

/* ---- one solve (numpy_path.py solve) for one pose -------------------------------------- */

typedef struct {
    double *f, *J; /* (K), (K, 2) work arrays */
} Work;

typedef struct {
    double att[2];
    long basis[3];
    int valid, converged, tips, iterations;
} Solve;

/* J_k = d f_k / d(roll, pitch) of candidate ck, with the ground's slope under it */
static void jacobian(const Map *m, const double *ck, const Rot *r, double px, double py,
                     double Jk[2])
{
    double h, hx, hy;
    double m0 = dot3(r->R[0], ck), m1 = dot3(r->R[1], ck);
    sample(m, px + m0, py + m1, &h, &hx, &hy);
    Jk[0] = hx * dot3(r->dRr[0], ck) + hy * dot3(r->dRr[1], ck) - dot3(r->dRr[2], ck);
    Jk[1] = hx * dot3(r->dRp[0], ck) + hy * dot3(r->dRp[1], ck) - dot3(r->dRp[2], ck);
}

static void touch_step(const double *f, const double Jt[3][2], const long tri[3], double out[2])
{
    double A[2][2] = {{Jt[0][0] - Jt[1][0], Jt[0][1] - Jt[1][1]},
                      {Jt[0][0] - Jt[2][0], Jt[0][1] - Jt[2][1]}};
    double fa = f[tri[0]];
    double b0 = f[tri[1]] - fa, b1 = f[tri[2]] - fa;
    double det = A[0][0] * A[1][1] - A[0][1] * A[1][0];
    if (!(fabs(det) > 1e-14)) {
        out[0] = out[1] = 0.0;
        return;
    }
    out[0] = (A[1][1] * b0 - A[0][1] * b1) / det;
    out[1] = (-A[1][0] * b0 + A[0][0] * b1) / det;
}

static void solve(const Map *m, const double *c, const long *idx, long Ks,
                  const long corners[4], const double com[3], const double pose[3],
                  const Settings *s, double tol_step, double final_step, const double att0[2],
                  const long *basis0, Work *w, Solve *out)
{
    double att[2] = {att0[0], att0[1]}, last[2] = {0.0, 0.0};
    long basis[3] = {Ks, Ks + 1, Ks + 2};
    if (basis0) basis[0] = basis0[0], basis[1] = basis0[1], basis[2] = basis0[2];
    out->valid = 1, out->converged = 0, out->tips = 0, out->iterations = 0;
    for (int it = 0; it <= s->max_iterations; ++it) {
        Rot r;
        rotations(pose[2], att[0], att[1], &r);
        if (!lift(m, c, idx, Ks, &r, pose[0], pose[1], w->f, w->J)) {
            out->valid = 0;
            break;
        }
        if (it == s->max_iterations) break;
        double q[2] = {-dot3(r.dRr[2], com), -dot3(r.dRp[2], com)};
        const long *warm = (it || basis0) ? basis : NULL;
        long before[3] = {basis[0], basis[1], basis[2]}, tri[3];
        double tip[2] = {0.0, 0.0}, newton[2] = {0.0, 0.0};
        int bounded = support_lp(w->J, w->f, Ks, q, warm, corners, tri, tip);
        basis[0] = tri[0], basis[1] = tri[1], basis[2] = tri[2];
        if (bounded) {
            double Jt[3][2];
            for (int j = 0; j < 3; ++j)
                jacobian(m, c + 3 * idx[tri[j]], &r, pose[0], pose[1], Jt[j]);
            touch_step(w->f, Jt, tri, newton);
        }
        /* long Newton steps are shortened (approach the rest from the side they start on) */
        if (sqrt(newton[0] * newton[0] + newton[1] * newton[1]) > s->approach)
            newton[0] *= s->approach_factor, newton[1] *= s->approach_factor;
        double step[2] = {bounded ? newton[0] : tip[0], bounded ? newton[1] : tip[1]};
        double norm = sqrt(step[0] * step[0] + step[1] * step[1]);
        int back = !bounded && sqrt(last[0] * last[0] + last[1] * last[1]) > 1e-7;
        int done = bounded && norm <= tol_step;
        int same = tri[0] == before[0] && tri[1] == before[1] && tri[2] == before[2];
        int last_step = !done && bounded && norm <= final_step && same;
        int over = !done && !back && (fabs(att[0]) > s->max_tilt || fabs(att[1]) > s->max_tilt);
        double limit = s->max_step * ldexp(1.0, -(it > 20 ? it - 20 : 0)); /* late cycles */
        double k = limit / (norm > 1e-300 ? norm : 1e-300);
        k = k < 1.0 ? k : 1.0;
        step[0] *= k, step[1] *= k;
        if (done || over) step[0] = step[1] = 0.0;
        done |= last_step;
        if (back) {
            last[0] *= 0.5, last[1] *= 0.5;
            step[0] = -last[0], step[1] = -last[1];
        } else if (bounded) {
            last[0] = step[0], last[1] = step[1];
        } else {
            last[0] = last[1] = 0.0;
        }
        att[0] += step[0], att[1] += step[1];
        out->iterations = it + 1;
        if (over) out->tips = 1;
        if (done) out->converged = 1;
        if (done || over) break;
    }
    out->att[0] = att[0], out->att[1] = att[1];
    out->basis[0] = basis[0], out->basis[1] = basis[1], out->basis[2] = basis[2];
}

/* indices of the n largest score (n <= K), in no particular order (quickselect) */
static void largest(const double *score, long *order, long K, long n)
{
    for (long k = 0; k < K; ++k) order[k] = k;
    long lo = 0, hi = K - 1;
    while (lo < hi) {
        double pivot = score[order[(lo + hi) / 2]];
        long i = lo, j = hi;
        while (i <= j) {
            while (score[order[i]] > pivot) ++i;
            while (score[order[j]] < pivot) --j;
            if (i <= j) {
                long tmp = order[i];
                order[i++] = order[j];
                order[j--] = tmp;
            }
        }
        if (n - 1 <= j) hi = j;
        else if (n - 1 >= i) lo = i;
        else break;
    }
}

/* ---- the stages (numpy_path.py numpy_rests and solve_active) --------------------------- */

/* Resting attitudes of n poses. Returns 0, or -1 when out of memory.
 *
 * elev (ny, nx), origin (2), res: the heightmap; c (K, 3): candidates in B [m];
 * coarse (Kc): the coarse subset; corners_coarse, corners_full (4): footprint corners in the
 * coarse subset's and in the full numbering; com (n, 3) [m]; poses (n, 3) (x, y, yaw);
 * settings (11): max_iterations, tol_step, max_step, max_tilt, approach, approach_factor,
 * coarse_tol, active_candidates, final_step, active_tol, (unused).
 * Out: att (n, 2) (roll, pitch) [rad], f (n, K) lifts at it [m] (NaN where invalid),
 * flags (n, 3) valid, converged, tips, iterations (n).
 */
int mmstab_rest(const double *elev, long ny, long nx, const double *origin, double res,
                const double *c, long K, const long *coarse, long Kc,
                const long *corners_coarse, const long *corners_full, const double *com,
                const double *poses, long n, const double *settings, double *att, double *f,
                unsigned char *flags, long *iterations)
{
    Map m = {elev, ny, nx, origin[0], origin[1], res};
    Settings s = {(int)settings[0], settings[1], settings[2], settings[3], settings[4],
                  settings[5], settings[6], settings[8], settings[9], (long)settings[7]};
    long M = s.active_candidates;
    int active = 0 < M && M < K;
    double *buf = malloc(sizeof(double) * (size_t)(4 * K));
    long *lbuf = malloc(sizeof(long) * (size_t)(2 * K + M + 1));
    if (!buf || !lbuf) {
        free(buf);
        free(lbuf);
        return -1;
    }
    Work w = {buf, buf + K};
    double *score = buf + 3 * K;
    long *all = lbuf, *order = lbuf + K, *sub = lbuf + 2 * K;
    for (long k = 0; k < K; ++k) all[k] = k;
    const long sub_corners[4] = {0, 1, 2, 3};
    for (long i = 0; i < n; ++i) {
        const double *p = poses + 3 * i, *g = com + 3 * i;
        double *fi = f + K * i;
        const double zero[2] = {0.0, 0.0};
        /* settle on a sparse subset of the candidates first */
        Solve s0, s1;
        solve(&m, c, coarse, Kc, corners_coarse, g, p, &s, s.coarse_tol, 0.0, zero, NULL, &w, &s0);
        long b0[3];
        for (int j = 0; j < 3; ++j)
            b0[j] = s0.basis[j] < Kc ? coarse[s0.basis[j]] : s0.basis[j] - Kc + K;
        long it = s0.iterations;
        Rot r;
        int valid;
        if (active) {
            /* then on this pose's M highest candidates (corners and triangle included) */
            rotations(p[2], s0.att[0], s0.att[1], &r);
            int valid0 = heights(&m, c, NULL, K, &r, p[0], p[1], fi);
            for (long k = 0; k < K; ++k) score[k] = valid0 ? fi[k] : 0.0;
            double v[3];
            for (int j = 0; j < 3; ++j)
                v[j] = b0[j] < K ? INFINITY : score[b0[j] < K ? b0[j] : K - 1];
            for (int j = 0; j < 3; ++j) score[b0[j] < K ? b0[j] : K - 1] = v[j];
            for (int j = 0; j < 4; ++j) score[corners_full[j]] = -INFINITY;
            largest(score, order, K, M - 4);
            for (int j = 0; j < 4; ++j) sub[j] = corners_full[j];
            for (long j = 0; j < M - 4; ++j) sub[4 + j] = order[j];
            long bs[3];
            for (int j = 0; j < 3; ++j) {
                if (b0[j] < K) {
                    bs[j] = 0;
                    for (long k = 0; k < M; ++k)
                        if (sub[k] == b0[j]) {
                            bs[j] = k;
                            break;
                        }
                } else {
                    bs[j] = b0[j] - K + M;
                }
            }
            solve(&m, c, sub, M, sub_corners, g, p, &s, s.tol_step, s.final_step, s0.att, bs,
                  &w, &s1);
            rotations(p[2], s1.att[0], s1.att[1], &r);
            int ok = heights(&m, c, NULL, K, &r, p[0], p[1], fi);
            double top = -INFINITY, high = -INFINITY;
            for (long k = 0; k < M; ++k) top = fi[sub[k]] > top ? fi[sub[k]] : top;
            for (long k = 0; k < K; ++k) high = fi[k] > high ? fi[k] : high;
            valid = valid0 && s1.valid && ok;
            int held = s1.converged && !s1.tips && high <= top + s.active_tol;
            it += s1.iterations;
            if (valid && !held) { /* a left-out candidate holds the body higher: all of them */
                solve(&m, c, all, K, corners_full, g, p, &s, s.tol_step, 0.0, s0.att, b0, &w,
                      &s1);
                it += s1.iterations;
                valid = s1.valid;
            }
        } else {
            solve(&m, c, all, K, corners_full, g, p, &s, s.tol_step, 0.0, s0.att, b0, &w, &s1);
            it += s1.iterations;
            valid = s1.valid;
        }
        rotations(p[2], s1.att[0], s1.att[1], &r);
        valid &= heights(&m, c, NULL, K, &r, p[0], p[1], fi);
        if (!valid)
            for (long k = 0; k < K; ++k) fi[k] = NAN;
        att[2 * i] = s1.att[0], att[2 * i + 1] = s1.att[1];
        flags[3 * i] = (unsigned char)valid;
        flags[3 * i + 1] = (unsigned char)s1.converged;
        flags[3 * i + 2] = (unsigned char)s1.tips;
        iterations[i] = it;
    }
    free(buf);
    free(lbuf);
    return 0;
}

/* ---- the polish (polish.py): the unsettled rows taken to the minimum of V --------------- */

/* polish.py's constants */
#define POLISH_MAX_ROUNDS 200
#define POLISH_FIRST_DELTA 0.02
#define POLISH_MAX_DELTA 0.1
#define POLISH_FLAT 1e-13
#define POLISH_SMALLEST_DELTA 1e-10
/* pieces the step's minimax may take in (beyond: the row keeps the rounds' answer) */
#define POLISH_MAX_PIECES 96

typedef struct {
    long K, cap;       /* candidates; the pieces' and the points' room */
    double *f, *J;     /* (K), (K, 2): the lifts and their gradients at the attitude */
    long *kept, *in;   /* the pieces the box can raise to the top; those taken in (S) */
    double *px, *py, *pv; /* the arrangement's points in the box, max over S there */
    long npts, ptcap;
} Minimax;

/* V [m] at attitude (roll, pitch): the highest lift plus the CoM's height; INFINITY where
 * a candidate needs ground off the map (polish.py: energy) */
static double energy(const Map *m, const double *c, long K, const double com[3],
                     const double pose[3], double roll, double pitch, double *f)
{
    Rot r;
    rotations(pose[2], roll, pitch, &r);
    if (!heights(m, c, NULL, K, &r, pose[0], pose[1], f)) return INFINITY;
    double top = -INFINITY;
    for (long k = 0; k < K; ++k) top = f[k] > top ? f[k] : top;
    return top + dot3(r.R[2], com);
}

static double piece(const Minimax *w, long k, double x, double y)
{
    return w->f[k] + (x * w->J[2 * k] + y * w->J[2 * k + 1]);
}

static int add_point(Minimax *w, double x, double y, double delta, long ns)
{
    double lim = delta * (1 + 1e-12);
    if (!(fabs(x) <= lim && fabs(y) <= lim)) return 1;
    if (w->npts == w->ptcap) return 0;
    x = x < -delta ? -delta : (x > delta ? delta : x);
    y = y < -delta ? -delta : (y > delta ? delta : y);
    double v = -INFINITY;
    for (long s = 0; s < ns; ++s) {
        double p = piece(w, w->in[s], x, y);
        v = p > v ? p : v;
    }
    w->px[w->npts] = x, w->py[w->npts] = y, w->pv[w->npts] = v;
    ++w->npts;
    return 1;
}

/* piece p taken into S (S holds ns pieces): the points raised to it, and the new points it
 * makes with S's pieces (box_minimax's pairs on the box's edges and triples) */
static int take_in(Minimax *w, long p, long ns, double delta)
{
    for (long i = 0; i < w->npts; ++i) {
        double v = piece(w, p, w->px[i], w->py[i]);
        w->pv[i] = v > w->pv[i] ? v : w->pv[i];
    }
    w->in[ns] = p;
    const double *Jp = w->J + 2 * p;
    for (long s = 0; s < ns; ++s) { /* p and q meet on n . d = cc */
        long q = w->in[s];
        double n0 = Jp[0] - w->J[2 * q], n1 = Jp[1] - w->J[2 * q + 1], cc = w->f[q] - w->f[p];
        for (int axis = 0; axis < 2; ++axis) {
            double na = axis ? n1 : n0, no = axis ? n0 : n1;
            if (!(fabs(no) > 1e-300)) continue;
            for (int side = -1; side <= 1; side += 2) {
                double e = side * delta, o = (cc - na * e) / no;
                if (!add_point(w, axis ? o : e, axis ? e : o, delta, ns + 1)) return 0;
            }
        }
    }
    for (long s = 0; s < ns; ++s) /* p, q, r meet at a point */
        for (long t = s + 1; t < ns; ++t) {
            long q = w->in[s], r = w->in[t];
            double A00 = Jp[0] - w->J[2 * q], A01 = Jp[1] - w->J[2 * q + 1];
            double A10 = Jp[0] - w->J[2 * r], A11 = Jp[1] - w->J[2 * r + 1];
            double b0 = w->f[q] - w->f[p], b1 = w->f[r] - w->f[p];
            double det = A00 * A11 - A01 * A10;
            if (!(fabs(det) > 1e-300)) continue;
            double x = (A11 * b0 - A01 * b1) / det, y = (A00 * b1 - A10 * b0) / det;
            if (!add_point(w, x, y, delta, ns + 1)) return 0;
        }
    return 1;
}

/* min over |d_i| <= delta of max_k (f_k + J_k . d) + g . d (polish.py: box_minimax): the
 * pieces the box can raise to the top kept; S grown from the piece highest at d = 0 by the
 * piece highest at S's minimiser until none rises above S there (then the minimiser is the
 * whole function's). 0: more pieces than the room. */
static int box_minimax(Minimax *w, const double g[2], double delta, double d[2], double *value)
{
    long K = w->K, m = 0, top = 0;
    double low = -INFINITY;
    for (long k = 0; k < K; ++k) {
        double reach = (fabs(w->J[2 * k]) + fabs(w->J[2 * k + 1])) * delta;
        low = w->f[k] - reach > low ? w->f[k] - reach : low;
    }
    for (long k = 0; k < K; ++k) {
        double reach = (fabs(w->J[2 * k]) + fabs(w->J[2 * k + 1])) * delta;
        if (w->f[k] + reach >= low - 1e-15) {
            if (m == 0 || w->f[k] > w->f[w->kept[top]]) top = m;
            w->kept[m++] = k;
        }
    }
    w->npts = 0;
    for (int i = 0; i < 4; ++i) /* the box's corners */
        add_point(w, (i & 2) ? delta : -delta, (i & 1) ? delta : -delta, delta, 0);
    long ns = 0;
    long p = w->kept[top];
    for (;;) {
        if (ns == w->cap || !take_in(w, p, ns, delta)) return 0;
        ++ns;
        long best = 0;
        double bv = INFINITY;
        for (long i = 0; i < w->npts; ++i) {
            double v = w->pv[i] + (w->px[i] * g[0] + w->py[i] * g[1]);
            if (v < bv) bv = v, best = i;
        }
        double x = w->px[best], y = w->py[best], hi = w->pv[best];
        p = -1;
        for (long j = 0; j < m; ++j) {
            double v = piece(w, w->kept[j], x, y);
            if (v > hi) hi = v, p = w->kept[j];
        }
        if (p < 0) {
            d[0] = x, d[1] = y, *value = bv;
            return 1;
        }
    }
}

/* the attitude of V's minimum reached from att (polish.py: lowest); 1: it ended there */
static int lowest(const Map *m, const double *c, long K, const double com[3],
                  const double pose[3], double att[2], Minimax *w, double *scratch)
{
    double a0 = att[0], a1 = att[1];
    double v = energy(m, c, K, com, pose, a0, a1, scratch);
    if (!isfinite(v)) return 0;
    double delta = POLISH_FIRST_DELTA;
    for (int round = 0; round < POLISH_MAX_ROUNDS; ++round) {
        Rot r;
        rotations(pose[2], a0, a1, &r);
        heights(m, c, NULL, K, &r, pose[0], pose[1], w->f);
        double z = -INFINITY;
        for (long k = 0; k < K; ++k) {
            z = w->f[k] > z ? w->f[k] : z;
            jacobian(m, c + 3 * k, &r, pose[0], pose[1], w->J + 2 * k);
        }
        double g[2] = {dot3(r.dRr[2], com), dot3(r.dRp[2], com)};
        double d[2], model;
        if (!box_minimax(w, g, delta, d, &model)) break; /* no room: unsettled */
        double predicted = z - model;
        if (!(predicted > POLISH_FLAT)) {
            att[0] = a0, att[1] = a1;
            return 1;
        }
        double v_new = energy(m, c, K, com, pose, a0 + d[0], a1 + d[1], scratch);
        double rho = (v - v_new) / predicted;
        if (rho > 0.1) {
            a0 += d[0], a1 += d[1], v = v_new;
            double big = fabs(d[0]) > fabs(d[1]) ? fabs(d[0]) : fabs(d[1]);
            if (rho > 0.75 && big >= 0.99 * delta)
                delta = 2.0 * delta < POLISH_MAX_DELTA ? 2.0 * delta : POLISH_MAX_DELTA;
        } else {
            delta *= 0.25;
            if (delta < POLISH_SMALLEST_DELTA) {
                att[0] = a0, att[1] = a1;
                return 1;
            }
        }
    }
    att[0] = a0, att[1] = a1;
    return 0;
}

/* n poses taken to V's minimum from att (polish.py: polish's rows), in place: att (n, 2),
 * and where it is reached with all its ground known, the lifts there f (n, K) and flags
 * (n, 2): ended, tips (beyond max_tilt). com (n, 3), poses (n, 3) as mmstab_rest's.
 * -1: out of memory. */
int mmstab_polish(const double *elev, long ny, long nx, const double *origin, double res,
                  const double *c, long K, const double *com, const double *poses, long n,
                  double max_tilt, double *att, double *f, unsigned char *flags)
{
    Map m = {elev, ny, nx, origin[0], origin[1], res};
    long cap = K < POLISH_MAX_PIECES ? K : POLISH_MAX_PIECES;
    long ptcap = 4 + 4 * cap * (cap - 1) / 2 + cap * (cap - 1) * (cap - 2) / 6;
    Minimax w = {K, cap, NULL, NULL, NULL, NULL, NULL, NULL, NULL, 0, ptcap};
    double *buf = malloc(sizeof(double) * (size_t)(3 * K + 3 * ptcap));
    long *lbuf = malloc(sizeof(long) * (size_t)(K + cap));
    if (!buf || !lbuf) {
        free(buf);
        free(lbuf);
        return -1;
    }
    w.f = buf, w.J = buf + K;
    w.px = buf + 3 * K, w.py = w.px + ptcap, w.pv = w.py + ptcap;
    w.kept = lbuf, w.in = lbuf + K;
    for (long i = 0; i < n; ++i) {
        double a[2] = {att[2 * i], att[2 * i + 1]}, *fi = f + K * i;
        if (!lowest(&m, c, K, com + 3 * i, poses + 3 * i, a, &w, fi)) continue;
        Rot r;
        rotations(poses[3 * i + 2], a[0], a[1], &r);
        if (!heights(&m, c, NULL, K, &r, poses[3 * i], poses[3 * i + 1], fi)) continue;
        att[2 * i] = a[0], att[2 * i + 1] = a[1];
        flags[2 * i] = 1;
        flags[2 * i + 1] = (unsigned char)(fabs(a[0]) > max_tilt || fabs(a[1]) > max_tilt);
    }
    free(buf);
    free(lbuf);
    return 0;
}
