/* Lower bounds on the distance of a segment to a box and of two segments: mmstab's C kernel
 * of mmstab/model/collision_distance.py (the arm's capsules against the base's boxes, the
 * turret's box and each other), many postures per call. No allocation, no static state.
 */
#include <math.h>

/* Distance of a point q in a box's frame to the box of half extents h. */
static double point_box(const double q[3], const double h[3])
{
    double s = 0.0;
    for (int i = 0; i < 3; i++) {
        double e = fabs(q[i]) - h[i];
        if (e > 0.0)
            s += e * e;
    }
    return sqrt(s);
}

/* n segments a0-a1 (n, 3) against boxes of half extents h (3,), centres C and rotations R
 * (row-major, box frame to B): one box for all (per_row 0: C (3,), R (9,)) or one per
 * segment (per_row 1: C (n, 3), R (n, 9)). The distance is convex along the segment:
 * golden-section search brackets a minimiser, and out[k] is the least distance found less
 * the segment's length times the bracket (the distance is 1-Lipschitz in the point): a
 * lower bound on the segment's distance [m]. The search stops once that bound reaches
 * ``stop`` [m] or a distance found is below it (the caller's question is decided); with
 * ``stop`` infinite after 90 steps (the bracket 0.618^90 ~ 1e-19 of the segment). */
int mmstab_segment_box(const double *a0, const double *a1, long n, const double *C,
                       const double *R, long per_row, const double *h, double stop,
                       double *out)
{
    const double g = 0.6180339887498949;
    for (long k = 0; k < n; k++) {
        const double *c = C + (per_row ? 3 * k : 0), *r = R + (per_row ? 9 * k : 0);
        double a[3], d[3];
        for (int i = 0; i < 3; i++) {
            double pa = 0.0, pb = 0.0;
            for (int j = 0; j < 3; j++) {
                pa += r[3 * j + i] * (a0[3 * k + j] - c[j]);
                pb += r[3 * j + i] * (a1[3 * k + j] - c[j]);
            }
            a[i] = pa;
            d[i] = pb - pa;
        }
        double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        double lo = 0.0, hi = 1.0, q[3];
        double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo), f1, f2;
        for (int i = 0; i < 3; i++)
            q[i] = a[i] + x1 * d[i];
        f1 = point_box(q, h);
        for (int i = 0; i < 3; i++)
            q[i] = a[i] + x2 * d[i];
        f2 = point_box(q, h);
        double best = f1 < f2 ? f1 : f2;
        const int exact = isinf(stop); /* to round-off: no question to decide */
        for (int it = 0; it < 90 && (exact || (best >= stop && best - len * (hi - lo) < stop));
             it++) {
            if (f1 <= f2) { /* a minimiser lies in [lo, x2] (convexity) */
                hi = x2;
                x2 = x1;
                f2 = f1;
                x1 = hi - g * (hi - lo);
                for (int i = 0; i < 3; i++)
                    q[i] = a[i] + x1 * d[i];
                f1 = point_box(q, h);
            } else {
                lo = x1;
                x1 = x2;
                f1 = f2;
                x2 = lo + g * (hi - lo);
                for (int i = 0; i < 3; i++)
                    q[i] = a[i] + x2 * d[i];
                f2 = point_box(q, h);
            }
            best = f1 < best ? f1 : best;
            best = f2 < best ? f2 : best;
        }
        out[k] = best - len * (hi - lo);
    }
    return 0;
}

static double clamp01(double x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }

/* Distance of segments a0-a1 and b0-b1 (n, 3 each) [m]: the closest points of two
 * segments (Ericson, Real-Time Collision Detection, 5.1.9), per row. */
int mmstab_segment_segment(const double *a0, const double *a1, const double *b0,
                           const double *b1, long n, double *out)
{
    for (long k = 0; k < n; k++) {
        const double *p1 = a0 + 3 * k, *q1 = a1 + 3 * k, *p2 = b0 + 3 * k, *q2 = b1 + 3 * k;
        double d1[3], d2[3], r[3];
        for (int i = 0; i < 3; i++) {
            d1[i] = q1[i] - p1[i];
            d2[i] = q2[i] - p2[i];
            r[i] = p1[i] - p2[i];
        }
        double a = d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2];
        double e = d2[0] * d2[0] + d2[1] * d2[1] + d2[2] * d2[2];
        double f = d2[0] * r[0] + d2[1] * r[1] + d2[2] * r[2];
        double s = 0.0, t = 0.0;
        if (a <= 1e-30 && e <= 1e-30) {
            s = t = 0.0;
        } else if (a <= 1e-30) {
            t = clamp01(f / e);
        } else {
            double c = d1[0] * r[0] + d1[1] * r[1] + d1[2] * r[2];
            if (e <= 1e-30) {
                s = clamp01(-c / a);
            } else {
                double b = d1[0] * d2[0] + d1[1] * d2[1] + d1[2] * d2[2];
                double den = a * e - b * b;
                s = den > 0.0 ? clamp01((b * f - c * e) / den) : 0.0;
                t = (b * s + f) / e;
                if (t < 0.0) {
                    t = 0.0;
                    s = clamp01(-c / a);
                } else if (t > 1.0) {
                    t = 1.0;
                    s = clamp01((b - c) / a);
                }
            }
        }
        double dd = 0.0;
        for (int i = 0; i < 3; i++) {
            double v = (p1[i] + d1[i] * s) - (p2[i] + d2[i] * t);
            dd += v * v;
        }
        out[k] = sqrt(dd);
    }
    return 0;
}

/* Every checked pair at every posture at once: near[k * P + j] = 1 where pair j may come
 * within ``need`` [m] at posture k (its bounds do not clear it), else 0.
 * Shapes: R (n, L, 9) row-major and p (n, L, 3), each link shape's pose in B (a capsule's
 * axis its z); kind[l] 1 capsule (hl[l] its half length, rad[l] its radius), 0 box (box
 * half extents hb[3 l..]); ball[l] its bounding sphere about p. Base boxes: bc (B, 3), br
 * (B, 9), bh (B, 3). Pairs: pa[j] a link, pb[j] a link (>= 0) or base box -1 - b; skip[j]
 * 1: the pair is not measured (near 0). slack_sphere [m] is taken off the bounding
 * spheres' gap, slack [m] off the segments' bounds. */
int mmstab_pairs_near(const double *R, const double *p, long n, long L, const long *kind,
                      const double *hl, const double *rad, const double *hb, const double *ball,
                      const double *bc, const double *br, const double *bh, long P,
                      const long *pa, const long *pb, const long *skip, double need,
                      double slack_sphere, double slack, unsigned char *near)
{
    for (long k = 0; k < n; k++) {
        for (long j = 0; j < P; j++) {
            unsigned char out = 0;
            long a = pa[j], b = pb[j];
            const double *Ra = R + (k * L + a) * 9, *pa3 = p + (k * L + a) * 3;
            if (skip[j]) {
                near[k * P + j] = 0;
                continue;
            }
            if (b < 0) { /* a link against a base box */
                long bb = -1 - b;
                const double *c = bc + 3 * bb, *r = br + 9 * bb, *h = bh + 3 * bb;
                double q[3];
                for (int i = 0; i < 3; i++) {
                    double s = 0.0;
                    for (int m = 0; m < 3; m++)
                        s += r[3 * m + i] * (pa3[m] - c[m]);
                    q[i] = s;
                }
                double gap = point_box(q, h) - ball[a] - slack_sphere;
                if (gap < need) {
                    out = 1;
                    if (kind[a] == 1) {
                        double e0[3], e1[3], o;
                        for (int i = 0; i < 3; i++) {
                            e0[i] = pa3[i] - Ra[3 * i + 2] * hl[a];
                            e1[i] = pa3[i] + Ra[3 * i + 2] * hl[a];
                        }
                        double stop = need + rad[a] + slack;
                        mmstab_segment_box(e0, e1, 1, c, r, 0, h, stop, &o);
                        out = o - slack - rad[a] < need;
                    }
                }
            } else { /* two links */
                const double *Rb = R + (k * L + b) * 9, *pb3 = p + (k * L + b) * 3;
                double dx = pa3[0] - pb3[0], dy = pa3[1] - pb3[1], dz = pa3[2] - pb3[2];
                double gap = sqrt(dx * dx + dy * dy + dz * dz) - ball[a] - ball[b] - slack_sphere;
                if (gap < need) {
                    out = 1;
                    double a0[3], a1[3], b0[3], b1[3], o;
                    for (int i = 0; i < 3; i++) {
                        a0[i] = pa3[i] - Ra[3 * i + 2] * hl[a];
                        a1[i] = pa3[i] + Ra[3 * i + 2] * hl[a];
                        b0[i] = pb3[i] - Rb[3 * i + 2] * hl[b];
                        b1[i] = pb3[i] + Rb[3 * i + 2] * hl[b];
                    }
                    if (kind[a] == 1 && kind[b] == 1) {
                        mmstab_segment_segment(a0, a1, b0, b1, 1, &o);
                        out = o - slack - rad[a] - rad[b] < need;
                    } else if (kind[a] == 1 || kind[b] == 1) { /* a box link and a capsule */
                        long cap = kind[a] == 1 ? a : b, box = kind[a] == 1 ? b : a;
                        const double *e0 = kind[a] == 1 ? a0 : b0, *e1 = kind[a] == 1 ? a1 : b1;
                        const double *Rx = R + (k * L + box) * 9, *px = p + (k * L + box) * 3;
                        double stop = need + rad[cap] + slack;
                        mmstab_segment_box(e0, e1, 1, px, Rx, 0, hb + 3 * box, stop, &o);
                        out = o - slack - rad[cap] < need;
                    }
                }
            }
            near[k * P + j] = out;
        }
    }
    return 0;
}
