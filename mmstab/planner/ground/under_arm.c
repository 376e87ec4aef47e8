/* The ground under the arm: mmstab's C kernel of mmstab/planner/under_arm.py's check.
 *
 * Two functions, each the NumPy function of the same name operation for operation, so both
 * paths give the same heights to rounding (tested on seeded random maps):
 *
 * - mmstab_arm_pieces: pieces_in_body, each piece's lowest point z_B (over the body's tilts
 *   up to a margin: tilted_height) and its centre in B, for n postures' link frames;
 * - mmstab_arm_heights: PoseGround.heights, each posture's least height above the ground
 *   under the arm at one pose, from those pieces and the pose's peak map (the rise's max
 *   over squares about every lattice block, built in NumPy).
 *
 * No allocation, no static state.
 */
#include <math.h>

/* Link frames (n, L, 4, 4) row-major; pieces: link (P,), points (P, 8, 3), radius (P,),
 * mid (P, 3) (the points' mean); margin: 0 for z itself, else cos and sin of it.
 * Out: low (n, P) [m], centre (n, P, 3) [m]. */
int mmstab_arm_pieces(const double *frames, long n, long L, const long *link,
                      const double *points, const double *radius, const double *mid,
                      long P, long margin, double cm, double sm, double *low,
                      double *centre)
{
    for (long k = 0; k < n; k++) {
        for (long p = 0; p < P; p++) {
            const double *F = frames + (k * L + link[p]) * 16;
            const double *pt = points + p * 24;
            double lo = INFINITY;
            for (int m = 0; m < 8; m++) {
                const double *a = pt + 3 * m;
                /* a capsule's segment ends come repeated: the same point gives the same z */
                if (m > 0 && a[0] == a[-3] && a[1] == a[-2] && a[2] == a[-1])
                    continue;
                double z = F[8] * a[0] + F[9] * a[1] + F[10] * a[2] + F[11];
                if (margin) { /* numpy.einsum's sum of 3 products: (0 + 2) + 1 */
                    z = (F[8] * a[0] + F[10] * a[2]) + F[9] * a[1] + F[11];
                    double x = (F[0] * a[0] + F[2] * a[2]) + F[1] * a[1] + F[3];
                    double y = (F[4] * a[0] + F[6] * a[2]) + F[5] * a[1] + F[7];
                    double tilted = z * cm - hypot(x, y) * sm;
                    z = tilted < z ? tilted : z;
                }
                lo = z < lo ? z : lo;
            }
            low[k * P + p] = lo - radius[p];
            const double *c = mid + 3 * p;
            double *o = centre + (k * P + p) * 3;
            for (int r = 0; r < 3; r++)
                o[r] = F[4 * r] * c[0] + F[4 * r + 1] * c[1] + F[4 * r + 2] * c[2] + F[4 * r + 3];
        }
    }
    return 0;
}

/* One pose: low (n, P) and centre (n, P, 3) from mmstab_arm_pieces; T the pose's M_T_B
 * (4, 4); cos_tilt its z-z entry; top the peak map's max [m]; above [m]: pieces that high
 * over the highest ground are not looked at closer; plane: pieces over ground not above
 * the support plane are +inf (left to the plane check); peak (rows, cols) with block (0, 0)
 * at lattice sample (i0, j0), blocks of block x block samples, lattice [m] steps; reach
 * [samples]: a piece's square with its blocks must lie this far inside the map (the NumPy
 * path would widen the map otherwise); slack [m].
 * Out: h (n,) [m]. Returns 1 when a piece's square lies outside the peak map (nothing
 * meaningful written then: the caller covers more ground and calls again). */
int mmstab_arm_heights(const double *low, const double *centre, long n, long P,
                       const double *T, double cos_tilt, double top, double above,
                       long plane, const double *peak, long rows, long cols, long i0,
                       long j0, long block, long reach, double lattice, double slack,
                       double *h)
{
    const double base = top > 0.0 ? top : 0.0;
    for (long k = 0; k < n; k++) {
        double least = INFINITY;
        for (long p = 0; p < P; p++) {
            double lowest = low[k * P + p] / cos_tilt;
            double v = lowest - base;
            if (v < above) {
                const double *c = centre + (k * P + p) * 3;
                double x = c[0] * T[0] + c[1] * T[1] + c[2] * T[2] + T[3];
                double y = c[0] * T[4] + c[1] * T[5] + c[2] * T[6] + T[7];
                long i = (long)floor(x / lattice) - i0, j = (long)floor(y / lattice) - j0;
                /* the square's blocks all inside the map, off its filter's edge */
                if (i < reach || j < reach || i + reach >= cols * block ||
                    j + reach >= rows * block)
                    return 1;
                double pk = peak[(j / block) * cols + i / block];
                v = pk > slack ? lowest - pk : (plane ? INFINITY : lowest);
            }
            /* np.min: a NaN anywhere makes the posture's answer NaN */
            if (isnan(v) || v < least)
                least = isnan(least) ? least : v;
        }
        h[k] = P ? least : 0.0;
    }
    return 0;
}
