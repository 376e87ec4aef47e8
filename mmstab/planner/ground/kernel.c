/* The ground under the arm: mmstab's C kernel of mmstab/planner/ground/'s one check, shared
 * by the offline planner (a route's poses on a terrain) and the online loop (a live map).
 *
 * Four functions, each its NumPy twin operation for operation, so both paths give the
 * same values (tested bit for bit on seeded random maps):
 *
 * - mmstab_arm_pieces: under_arm.pieces_in_body, each piece's lowest point z_B (over the
 *   body's tilts up to a margin: tilted_height) and its centre in B, for n postures' link
 *   frames;
 * - mmstab_arm_heights: under_arm.PoseGround.heights, each posture's least height above the
 *   ground under the arm at one pose, from those pieces and the pose's peak map (the rise's
 *   max over squares about every lattice block, mmstab_peak_map's);
 * - mmstab_peak_map: under_arm.PoseGround._build, a pose's peak map from the ground's tiles
 *   (the rise above the support plane, its max over blocks, then over squares of blocks);
 * - mmstab_lattice_peak: on a live map (map_lattice.MapPoseGround), the same peaks computed
 *   only where a piece asks and kept: the NumPy path samples a pose's ground on the 1 cm
 *   lattice by tiles of 64 x 64 samples around every piece it looks at, takes the rise above
 *   the support plane, its max over blocks of 2 x 2 samples, then the max over the
 *   (2 half + 1)^2 blocks about each block; here a block's max, a row of blocks' max and a
 *   block's peak are each computed once per pose (NaN: not yet). Every operation is the
 *   NumPy path's, in its order (the bilinear sample along x, then y; the unknown at the
 *   plane plus the fill).
 *
 * No static state; the lattice's caches belong to the caller.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Link frames (n, L, 4, 4) row-major; pieces: link (P,), points (P, 8, 3), radius (P,),
 * mid (P, 3) (the points' mean); margin: 0 for z itself, else cos and sin of it.
 * Out: low (n, P) [m], centre (n, P, 3) [m].
 *
 * A piece whose link's frame is the previous posture's, bit for bit (postures that share
 * their first joints, taken in order), gets the previous posture's values: the same
 * arithmetic on the same numbers. */
int mmstab_arm_pieces(const double *frames, long n, long L, const long *link,
                      const double *points, const double *radius, const double *mid,
                      long P, long margin, double cm, double sm, double *low,
                      double *centre)
{
    for (long k = 0; k < n; k++) {
        int same = 0;
        for (long p = 0; p < P; p++) {
            const double *F = frames + (k * L + link[p]) * 16;
            if (k > 0 && (p == 0 || link[p] != link[p - 1])) /* the frame's rows 0-2 */
                same = memcmp(F, F - L * 16, 12 * sizeof(double)) == 0;
            if (same) {
                low[k * P + p] = low[(k - 1) * P + p];
                for (int r = 0; r < 3; r++)
                    centre[(k * P + p) * 3 + r] = centre[((k - 1) * P + p) * 3 + r];
                continue;
            }
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

/* One pose: low (m, P) and centre (m, P, 3) from mmstab_arm_pieces, posture k's at row
 * at[k] (at NULL: row k); T the pose's M_T_B
 * (4, 4); cos_tilt its z-z entry; top the peak map's max [m]; above [m]: pieces that high
 * over the highest ground are not looked at closer; plane: pieces over ground not above
 * the support plane are +inf (left to the plane check); peak (rows, cols) with block (0, 0)
 * at lattice sample (i0, j0), blocks of block x block samples, lattice [m] steps; reach
 * [samples]: a piece's square with its blocks must lie this far inside the map (the NumPy
 * path would widen the map otherwise); slack [m].
 * Out: h (n,) [m]. Returns 1 when a piece's square lies outside the peak map (nothing
 * meaningful written then: the caller covers more ground and calls again). */
int mmstab_arm_heights(const double *low, const double *centre, const long *at, long n,
                       long P, const double *T, double cos_tilt, double top, double above,
                       long plane, const double *peak, long rows, long cols, long i0,
                       long j0, long block, long reach, double lattice, double slack,
                       double *h)
{
    const double base = top > 0.0 ? top : 0.0;
    for (long k = 0; k < n; k++) {
        double least = INFINITY;
        const long r = at ? at[k] : k; /* the posture's row of low and centre */
        for (long p = 0; p < P; p++) {
            double lowest = low[r * P + p] / cos_tilt;
            double v = lowest - base;
            if (v < above) {
                const double *c = centre + (r * P + p) * 3;
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

/* ---- a live map's peaks (mmstab_lattice_peak) ---- */

typedef struct {
    long i;
    double f, term;
    int inside;
} Line; /* a lattice line's place on the map along one axis (line()) */

typedef struct {
    const double *elev; /* (ny, nx) row-major elevation [m], NaN = unknown */
    long ny, nx;
    double ox, oy; /* M (x, y) of the centre of cell [0, 0] [m] */
    double res;    /* [m/cell] */
    double n0, n1, n2, p0, p1, p2; /* the support plane: B's z axis and origin in M */
    double fill;                   /* an unknown sample's rise above the plane [m] */
    double lattice;                /* the lattice's step [m] */
    long block, half;              /* samples along a block's edge; the peak's half-width */
    long bi0, bj0, nbi, nbj;       /* the cached blocks: first block (x, y), counts */
    double *blocks, *rows, *peaks; /* (nbj, nbi) each, NaN = not computed yet */
    Line *xs, *ys;                 /* the cached blocks' lattice lines along x and y */
} Ground;

/* Floor division (Python's //) of an index by a positive step. */
static long floor_div(long a, long b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

/* A lattice line's place on the map along one axis (x: k, the columns; y: l, the rows):
 * lattice_z's index of the cell, its fraction, whether inside, and the plane's term
 * (n_x (x - p_x), in the NumPy path's order), computed once a call. */
static Line line(double c, double origin, double res, long n, double normal, double at)
{
    const double eps = 1e-9;
    double u = (c - origin) / res, fu = floor(u);
    fu = fu < 0.0 ? 0.0 : (fu > (double)(n - 2) ? (double)(n - 2) : fu);
    Line out = {(long)fu, u - (double)(long)fu, normal * (c - at),
                u >= -eps && u <= (double)(n - 1) + eps};
    return out;
}

/* The rise above the support plane of the lattice sample on lines (x, y): map_lattice's
 * lattice_z bilinear height (+inf off the map or unknown), filled, less the plane. */
static double rise(const Ground *g, const Line *x, const Line *y)
{
    const double *r0 = g->elev + y->i * g->nx, *r1 = r0 + g->nx;
    double a = r0[x->i] + x->f * (r0[x->i + 1] - r0[x->i]);
    double b = r1[x->i] + x->f * (r1[x->i + 1] - r1[x->i]);
    double z = a + y->f * (b - a);
    double plane = g->p2 - (x->term + y->term) / g->n2;
    if (!(x->inside && y->inside && isfinite(z)))
        z = plane + g->fill;
    return z - plane;
}

/* The max of the rise over block (bi, bj) (cache indices). */
static double block_max(Ground *g, long bi, long bj)
{
    double *c = g->blocks + bj * g->nbi + bi;
    if (isnan(*c)) {
        double m = -INFINITY;
        for (long dl = 0; dl < g->block; dl++)
            for (long dk = 0; dk < g->block; dk++) {
                double r = rise(g, g->xs + bi * g->block + dk, g->ys + bj * g->block + dl);
                m = r > m ? r : m;
            }
        *c = m;
    }
    return *c;
}

/* The max over blocks bi - half .. bi + half of row bj. */
static double row_max(Ground *g, long bi, long bj)
{
    double *c = g->rows + bj * g->nbi + bi;
    if (isnan(*c)) {
        double m = -INFINITY;
        for (long d = -g->half; d <= g->half; d++) {
            double r = block_max(g, bi + d, bj);
            m = r > m ? r : m;
        }
        *c = m;
    }
    return *c;
}

/* The max over the (2 half + 1)^2 blocks about block (bi, bj). */
static double peak(Ground *g, long bi, long bj)
{
    double *c = g->peaks + bj * g->nbi + bi;
    if (isnan(*c)) {
        double m = -INFINITY;
        for (long d = -g->half; d <= g->half; d++) {
            double r = row_max(g, bi, bj + d);
            m = r > m ? r : m;
        }
        *c = m;
    }
    return *c;
}

/* Peaks at the lattice samples (i[p], j[p]), p < m, into out. The map: elev (ny, nx),
 * origin (2,), res; plane = (n0, n1, n2, p0, p1, p2); steps = (lattice, fill);
 * sizes = (block, half, bi0, bj0, nbi, nbj). Returns 0, or 1 when a sample's square leaves
 * the cached blocks, 2 when out of memory (out then incomplete: the caller takes the NumPy
 * path). */
int mmstab_lattice_peak(const double *elev, long ny, long nx, const double *origin,
                        double res, const double *plane, const double *steps,
                        const long *sizes, double *blocks, double *rows, double *peaks,
                        const long *i, const long *j, long m, double *out)
{
    Ground g = {elev, ny, nx, origin[0], origin[1], res,
                plane[0], plane[1], plane[2], plane[3], plane[4], plane[5],
                steps[1], steps[0], sizes[0], sizes[1], sizes[2], sizes[3], sizes[4],
                sizes[5], blocks, rows, peaks, NULL, NULL};
    long nk = g.nbi * g.block, nl = g.nbj * g.block, code = 0;
    g.xs = malloc((size_t)(nk + nl) * sizeof(Line));
    if (g.xs == NULL)
        return 2;
    g.ys = g.xs + nk;
    for (long k = 0; k < nk; k++)
        g.xs[k] = line((double)(g.bi0 * g.block + k) * g.lattice, g.ox, g.res, nx, g.n0, g.p0);
    for (long l = 0; l < nl; l++)
        g.ys[l] = line((double)(g.bj0 * g.block + l) * g.lattice, g.oy, g.res, ny, g.n1, g.p1);
    for (long p = 0; p < m && code == 0; p++) {
        long bi = floor_div(i[p], g.block) - g.bi0, bj = floor_div(j[p], g.block) - g.bj0;
        if (bi < g.half || bj < g.half || bi >= g.nbi - g.half || bj >= g.nbj - g.half)
            code = 1;
        else
            out[p] = peak(&g, bi, bj);
    }
    free(g.xs);
    return (int)code;
}

/* ---- a pose's peak map on a terrain's lattice (mmstab_peak_map) ---- */

/* under_arm.PoseGround._build: the rise of the ground's z_M on the lattice samples of
 * tiles[tj * ntx + ti] (tile x tile samples each, rows along y; ti < ntx, tj < nty; sample
 * (i0, j0) first) above the support plane of T (the pose's M_T_B, 4 x 4), its max over
 * blocks of block x block samples into blocks (nty tile / block, ntx tile / block), and the
 * max over the (2 half + 1)^2 blocks about each block (the edge's block repeated beyond
 * it: scipy's maximum_filter, mode "nearest") into peak; rise (2 ntx tile) and rows (blocks'
 * size): scratch. The plane's z_M is plane_z's arithmetic, in its order; max is exact, so
 * the same values as NumPy's and SciPy's for samples not NaN (the caller takes NumPy's
 * path for tiles with a NaN). Returns the blocks' max (top). */
double mmstab_peak_map(const double *const *tiles, long ntx, long nty, long tile, long i0,
                       long j0, double lattice, const double *T, long block, long half,
                       double *rise, double *blocks, double *rows, double *peak)
{
    const double n0 = T[2], n1 = T[6], n2 = T[10], o0 = T[3], o1 = T[7], o2 = T[11];
    const long nx = ntx * tile, ny = nty * tile, bx = nx / block, by = ny / block;
    double top = -INFINITY, *xs = rise + nx; /* the plane's term along x */
    for (long i = 0; i < nx; i++)
        xs[i] = n0 * ((double)(i0 + i) * lattice - o0);
    for (long j = 0; j < ny; j++) {
        const double ty = n1 * ((double)(j0 + j) * lattice - o1);
        for (long t = 0; t < ntx; t++) {
            const double *z = tiles[(j / tile) * ntx + t] + (j % tile) * tile;
            double *r = rise + t * tile;
            const double *x = xs + t * tile;
            for (long i = 0; i < tile; i++)
                r[i] = z[i] - (o2 - (x[i] + ty) / n2);
        }
        double *b = blocks + (j / block) * bx;
        if (j % block == 0)
            for (long i = 0; i < bx; i++)
                b[i] = -INFINITY;
        for (long k = 0; k < bx; k++)
            for (long d = 0; d < block; d++) {
                double v = rise[k * block + d];
                b[k] = v > b[k] ? v : b[k];
            }
    }
    for (long k = 0; k < bx * by; k++)
        top = blocks[k] > top ? blocks[k] : top;
    for (long j = 0; j < by; j++) { /* the max along a row, then along a column */
        const double *b = blocks + j * bx;
        double *r = rows + j * bx;
        for (long i = 0; i < bx; i++)
            r[i] = b[i];
        for (long d = 1; d <= half; d++)
            for (long i = 0; i < bx; i++) {
                double lo = b[i - d < 0 ? 0 : i - d], hi = b[i + d >= bx ? bx - 1 : i + d];
                double m = lo > hi ? lo : hi;
                r[i] = m > r[i] ? m : r[i];
            }
    }
    for (long j = 0; j < by; j++) {
        double *p = peak + j * bx;
        const double *r = rows + j * bx;
        for (long i = 0; i < bx; i++)
            p[i] = r[i];
        for (long d = 1; d <= half; d++) {
            const double *lo = rows + (j - d < 0 ? 0 : j - d) * bx;
            const double *hi = rows + (j + d >= by ? by - 1 : j + d) * bx;
            for (long i = 0; i < bx; i++) {
                double m = lo[i] > hi[i] ? lo[i] : hi[i];
                p[i] = m > p[i] ? m : p[i];
            }
        }
    }
    return top;
}
