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
