/* The ground's peak under the arm's pieces on a live map's lattice: mmstab's C kernel.
 *
 * The NumPy path (mmstab/runs/online/map_lattice.py, mmstab/planner/under_arm.py) samples
 * a pose's ground on the 1 cm lattice by tiles of 64 x 64 samples around every piece it
 * looks at, takes the rise above the support plane, its max over blocks of 2 x 2 samples,
 * then the max over the (2 half + 1)^2 blocks about each block. Here the same values are
 * computed only where a piece asks for them, and kept: a block's max, a row of blocks' max
 * and a block's peak are each computed once per pose (NaN: not yet). Every operation is
 * the NumPy path's, in its order (the bilinear sample along x, then y; the unknown at the
 * plane plus the fill), so both give the same peaks (tested).
 *
 * No static state; the caches belong to the caller.
 */
#include <math.h>
#include <stdlib.h>

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
