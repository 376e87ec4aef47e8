/* The slide limit's grid over the overall CoMs of many rows (turning.py's grid_slides).
 *
 * Rows' arm CoMs in B become overall CoMs as Robot.overall_com computes them,
 * (m_a g_a + m_b g_b) / m_T; mmstab_turn_extent takes their extent, and
 * mmstab_turn_trilinear reads each row's value off tables on the grid over that extent,
 * trilinear between the nodes, the coordinates clamped to the grid (scipy's map_coordinates,
 * order 1, mode "nearest": the NumPy twin; they agree to round-off,
 * tests/planner/test_turn_slide.py). One pass over the rows each, no temporaries.
 */
#include <math.h>

static void overall(const double *arm, const double *ma_mb, const double *cb, double mt,
                    double *o) {
    for (int i = 0; i < 3; ++i) o[i] = (ma_mb[0] * arm[i] + ma_mb[1] * cb[i]) / mt;
}

/* rows (n,) of arm_com (., 3) [m]; ma_mb = (m_a, m_b) [kg], cb the base's CoM (3,) [m], mt
 * [kg]. Out: lo, hi (3,) [m]. */
int mmstab_turn_extent(long n, const long *rows, const double *arm_com, const double *ma_mb,
                       const double *cb, double mt, double *lo, double *hi) {
    for (int i = 0; i < 3; ++i) {
        lo[i] = INFINITY;
        hi[i] = -INFINITY;
    }
    for (long k = 0; k < n; ++k) {
        double o[3];
        overall(arm_com + 3 * rows[k], ma_mb, cb, mt, o);
        for (int i = 0; i < 3; ++i) {
            if (o[i] < lo[i]) lo[i] = o[i];
            if (o[i] > hi[i]) hi[i] = o[i];
        }
    }
    return 0;
}

/* Tables (C, nodes[0], nodes[1], nodes[2]) row-major; axis i's nodes start at a0[i], step
 * da[i] apart (an axis of one node: every row at 0); scale (C,) multiplies table c's value.
 * Out: out (C, n). */
int mmstab_turn_trilinear(long n, const long *rows, const double *arm_com,
                          const double *ma_mb, const double *cb, double mt, long C,
                          const double *tables, const long *nodes, const double *a0,
                          const double *da, const double *scale, double *out) {
    const long size = nodes[0] * nodes[1] * nodes[2];
    const long stride[3] = {nodes[1] * nodes[2], nodes[2], 1};
    for (long k = 0; k < n; ++k) {
        double o[3];
        overall(arm_com + 3 * rows[k], ma_mb, cb, mt, o);
        long base = 0, step[3];
        double w[3];
        for (int i = 0; i < 3; ++i) {
            double t = nodes[i] > 1 ? (o[i] - a0[i]) / da[i] : 0.0;
            double top = (double)(nodes[i] - 1);
            if (!(t > 0.0)) t = 0.0; /* NaN too: the first node */
            if (t > top) t = top;
            long j = (long)floor(t);
            if (j >= nodes[i] - 1) j = nodes[i] > 1 ? nodes[i] - 2 : 0;
            w[i] = nodes[i] > 1 ? t - (double)j : 0.0;
            step[i] = nodes[i] > 1 ? stride[i] : 0;
            base += j * stride[i];
        }
        for (long c = 0; c < C; ++c) {
            const double *T = tables + c * size + base;
            double v = 0.0;
            for (int corner = 0; corner < 8; ++corner) {
                double weight = 1.0;
                long at = 0;
                for (int i = 0; i < 3; ++i) {
                    int up = (corner >> (2 - i)) & 1;
                    weight *= up ? w[i] : 1.0 - w[i];
                    at += up ? step[i] : 0;
                }
                if (weight != 0.0) v += weight * T[at];
            }
            out[c * n + k] = v * scale[c];
        }
    }
    return 0;
}
