/* The force-angle μ of many states on their loaded support (mmstab.stability.support_kernel).
 *
 * Per state: the bearing contact candidates placed in G by the state's rest G_T_B, their
 * hull seen along the net force (Andrew's monotone chain in the plane (u, v) normal to it,
 * counter-clockwise about -force, points on an edge dropped), and the minimum over the
 * hull's edges of the force angle (Papadopoulos and Rey; mmstab.stability.static.axis_angles,
 * the same products). A state whose contacts are fewer than three, nearly on a line seen
 * along the force, or whose hull has two vertices closer than `tol` (merge_close would act)
 * is left to the Python path: ok = 0.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

static double dot3(const double *a, const double *b) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* 2-D cross product of (a - o) and (b - o) */
static double turn(const double *x, const double *y, long o, long a, long b) {
    return (x[a] - x[o]) * (y[b] - y[o]) - (y[a] - y[o]) * (x[b] - x[o]);
}

/* sort idx[0..m) by (x, then y): insertion sort (a state bears tens of candidates) */
static void sort_xy(long *idx, long m, const double *x, const double *y) {
    for (long i = 1; i < m; i++) {
        long k = idx[i], j = i - 1;
        while (j >= 0 && (x[idx[j]] > x[k] || (x[idx[j]] == x[k] && y[idx[j]] > y[k]))) {
            idx[j + 1] = idx[j];
            j--;
        }
        idx[j + 1] = k;
    }
}

/* Returns 0, or -1 when out of memory.
 *
 * points: (K, 3) candidates in B; bearing: (n, K) 0/1; G_T_B: (n, 4, 4) row-major;
 * com_body: (n, 3) in B; force: (3,) in G [N]; u, v: (3,) the plane normal to the force,
 * (u, v, -force) right-handed; tol: merge distance [m].
 * mu: (n,) [N rad] (written where ok); ok: (n,) 0/1.
 */
int mmstab_support_mu(long n, long K, const double *points, const unsigned char *bearing,
                      const double *G_T_B, const double *com_body, const double *force,
                      const double *u, const double *v, double tol, double *mu,
                      unsigned char *ok) {
    double *P = malloc(sizeof(double) * 3 * (size_t)(K > 0 ? K : 1));
    double *x = malloc(sizeof(double) * (size_t)(K > 0 ? K : 1));
    double *y = malloc(sizeof(double) * (size_t)(K > 0 ? K : 1));
    long *idx = malloc(sizeof(long) * (size_t)(K > 0 ? K : 1));
    long *hull = malloc(sizeof(long) * (size_t)(2 * K + 2));
    if (!P || !x || !y || !idx || !hull) {
        free(P); free(x); free(y); free(idx); free(hull);
        return -1;
    }
    const double fnorm = sqrt(dot3(force, force));
    for (long i = 0; i < n; i++) {
        const double *T = G_T_B + 16 * i;
        const unsigned char *b = bearing + K * i;
        ok[i] = 0;
        long m = 0;
        double centre[3] = {0.0, 0.0, 0.0};
        for (long j = 0; j < K; j++) {
            if (!b[j]) continue;
            const double *c = points + 3 * j;
            double *p = P + 3 * m;
            for (int r = 0; r < 3; r++)
                p[r] = T[4 * r] * c[0] + T[4 * r + 1] * c[1] + T[4 * r + 2] * c[2] + T[4 * r + 3];
            for (int r = 0; r < 3; r++) centre[r] += p[r];
            m++;
        }
        if (m < 3) continue;
        for (int r = 0; r < 3; r++) centre[r] /= (double)m;
        double a = 0.0, bb = 0.0, cc = 0.0;
        for (long j = 0; j < m; j++) {
            double rel[3] = {P[3 * j] - centre[0], P[3 * j + 1] - centre[1], P[3 * j + 2] - centre[2]};
            x[j] = dot3(rel, u);
            y[j] = dot3(rel, v);
            a += x[j] * x[j];
            bb += x[j] * y[j];
            cc += y[j] * y[j];
            idx[j] = j;
        }
        a /= (double)m; bb /= (double)m; cc /= (double)m;
        double big = 0.5 * (a + cc) + sqrt(0.25 * (a - cc) * (a - cc) + bb * bb);
        if (!(big > 0.0)) continue;
        double small = (a * cc - bb * bb) / big;
        if (!(small > 1e-12 * big)) continue; /* nearly a line: the Python path's extreme pair */
        sort_xy(idx, m, x, y);
        long h = 0;
        for (long j = 0; j < m; j++) { /* lower chain */
            while (h >= 2 && turn(x, y, hull[h - 2], hull[h - 1], idx[j]) <= 0.0) h--;
            hull[h++] = idx[j];
        }
        for (long j = m - 2, low = h + 1; j >= 0; j--) { /* upper chain */
            while (h >= low && turn(x, y, hull[h - 2], hull[h - 1], idx[j]) <= 0.0) h--;
            hull[h++] = idx[j];
        }
        h--; /* the first point closes the ring */
        if (h < 3) continue;
        int close = 0;
        for (long j = 0; j < h && !close; j++) {
            const double *p = P + 3 * hull[j], *q = P + 3 * hull[(j + 1) % h];
            double e[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
            close = sqrt(dot3(e, e)) < tol;
        }
        if (close) continue;
        const double *cb = com_body + 3 * i;
        double g[3];
        for (int r = 0; r < 3; r++)
            g[r] = T[4 * r] * cb[0] + T[4 * r + 1] * cb[1] + T[4 * r + 2] * cb[2] + T[4 * r + 3];
        double least = INFINITY;
        for (long j = 0; j < h; j++) {
            const double *p = P + 3 * hull[j], *q = P + 3 * hull[(j + 1) % h];
            double e[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
            double len = sqrt(dot3(e, e));
            double ah[3] = {e[0] / len, e[1] / len, e[2] / len};
            double d[3] = {q[0] - g[0], q[1] - g[1], q[2] - g[2]};
            double da = dot3(d, ah), fa = dot3(force, ah);
            double l[3] = {d[0] - da * ah[0], d[1] - da * ah[1], d[2] - da * ah[2]};
            double fj[3] = {force[0] - fa * ah[0], force[1] - fa * ah[1], force[2] - fa * ah[2]};
            double cr[3] = {l[1] * fj[2] - l[2] * fj[1], l[2] * fj[0] - l[0] * fj[2],
                            l[0] * fj[1] - l[1] * fj[0]};
            double theta = atan2(dot3(cr, ah), dot3(l, fj));
            if (theta < least) least = theta;
        }
        mu[i] = least * fnorm;
        ok[i] = 1;
    }
    free(P); free(x); free(y); free(idx); free(hull);
    return 0;
}
