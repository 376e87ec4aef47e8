/* The arm's least height above a heightmap at N body poses: points on the arm's surface
 * against the map's bilinear height vertically under each (mmstab.runs.arm_ground's
 * arm_heights, whose NumPy path is its twin, operation for operation).
 *
 * frames: (n, L, 4, 4) row-major, each link's pose in G; link (Q,), points (Q, 3) in their
 * links' frames; elev (ny, nx) row-major, origin (2,), res; bounds (x0, x1, y0, y1): a point
 * beyond them takes the edge's ground. Out: least (n,) [m], known (n,): every point over a
 * known (finite) cell. Returns 0.
 */
#include <math.h>

static double clip(double a, double lo, double hi) { return a < lo ? lo : (a > hi ? hi : a); }

int mmstab_arm_heights(long n, long L, const double *frames, long Q, const long *link,
                       const double *points, const double *elev, long ny, long nx,
                       const double *origin, double res, const double *bounds, double *least,
                       unsigned char *known) {
    const double inv = 1.0 / res;
    for (long i = 0; i < n; ++i) {
        const double *F = frames + i * L * 16;
        double lo = INFINITY;
        int ok = 1;
        for (long q = 0; q < Q; ++q) {
            const double *T = F + link[q] * 16, *p = points + 3 * q;
            double x = T[0] * p[0] + T[1] * p[1] + T[2] * p[2] + T[3];
            double y = T[4] * p[0] + T[5] * p[1] + T[6] * p[2] + T[7];
            double z = T[8] * p[0] + T[9] * p[1] + T[10] * p[2] + T[11];
            x = clip(x, bounds[0], bounds[1]);
            y = clip(y, bounds[2], bounds[3]);
            double u = (x - origin[0]) * inv, v = (y - origin[1]) * inv;
            long ix = (long)(u > 0.0 ? u : 0.0), iy = (long)(v > 0.0 ? v : 0.0);
            if (ix > nx - 2) ix = nx - 2;
            if (iy > ny - 2) iy = ny - 2;
            double fx = u - (double)ix, fy = v - (double)iy;
            long k = iy * nx + ix;
            double h00 = elev[k], h10 = elev[k + 1], h01 = elev[k + nx], h11 = elev[k + nx + 1];
            double low = h00 + fx * (h10 - h00);
            double g = low + fy * (h01 + fx * (h11 - h01) - low);
            if (!isfinite(g)) {
                ok = 0;
                continue;
            }
            double h = z - g;
            if (h < lo) lo = h;
        }
        least[i] = lo;
        known[i] = (unsigned char)ok;
    }
    return 0;
}
