/* The arm's link frames and link shapes' poses in B, the numbers BLAS gives (frames.py).
 *
 * NumPy's matmul of a stack of 4x4 (3x3) float64 matrices calls BLAS once per matrix;
 * OpenBLAS's kernel sums each entry with fused multiply-adds in k order from zero, its
 * matrix-vector kernel a row's three products in the order 1, 0, 2. The same operations
 * here, on a whole batch in one call (frames.py checks the two agree bit for bit on this
 * machine before it uses them, else NumPy's own path is kept).
 *
 * trig (n, L, 2): cos and sin of each joint angle plus its offset; gain (L, 8) and rest
 * (L, 8): a DH transform's first two rows are trig[c] * gain (c per entry: sel), its last
 * two rows rest; mount (4, 4); frames out (n, L, 4, 4).
 * Shapes: Rs (L, 3, 3), ps (L, 3) the shapes' poses in their links' frames; R out
 * (n, L, 3, 3), p out (n, L, 3).
 * Returns -1 where the CPU has no FMA (nothing written).
 */
#include <stddef.h>

static const int SEL[8] = {0, 1, 1, 0, 1, 0, 0, 1};

__attribute__((target("fma"))) static void mm4(const double *a, const double *b, double *c) {
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            double s = __builtin_fma(a[4 * i], b[j], 0.0);
            s = __builtin_fma(a[4 * i + 1], b[4 + j], s);
            s = __builtin_fma(a[4 * i + 2], b[8 + j], s);
            c[4 * i + j] = __builtin_fma(a[4 * i + 3], b[12 + j], s);
        }
}

__attribute__((target("fma"))) static void frames_fma(
    const double *trig, const double *gain, const double *rest, const double *mount,
    long n, long L, double *frames) {
    double D[16];
    for (long t = 0; t < n; t++) {
        const double *prev = mount;
        for (long l = 0; l < L; l++) {
            const double *cs = trig + 2 * (t * L + l), *g = gain + 8 * l, *r = rest + 8 * l;
            for (int e = 0; e < 8; e++) D[e] = cs[SEL[e]] * g[e];
            for (int e = 0; e < 8; e++) D[8 + e] = r[e];
            double *out = frames + 16 * (t * L + l);
            mm4(prev, D, out);
            prev = out;
        }
    }
}

__attribute__((target("fma"))) static void shapes_fma(
    const double *frames, const double *Rs, const double *ps, long n, long L, double *R,
    double *p) {
    for (long t = 0; t < n; t++)
        for (long l = 0; l < L; l++) {
            const double *F = frames + 16 * (t * L + l), *b = Rs + 9 * l, *v = ps + 3 * l;
            double *o = R + 9 * (t * L + l), *q = p + 3 * (t * L + l);
            for (int i = 0; i < 3; i++) {
                const double *a = F + 4 * i;
                for (int j = 0; j < 3; j++) {
                    double s = __builtin_fma(a[0], b[j], 0.0);
                    s = __builtin_fma(a[1], b[3 + j], s);
                    o[3 * i + j] = __builtin_fma(a[2], b[6 + j], s);
                }
                double s = __builtin_fma(a[2], v[2], __builtin_fma(a[0], v[0], a[1] * v[1]));
                q[i] = s + a[3];
            }
        }
}

int mmstab_link_frames(const double *trig, const double *gain, const double *rest,
                       const double *mount, long n, long L, double *frames) {
    if (!__builtin_cpu_supports("fma")) return -1;
    frames_fma(trig, gain, rest, mount, n, L, frames);
    return 0;
}

int mmstab_shape_poses(const double *frames, const double *Rs, const double *ps, long n,
                       long L, double *R, double *p) {
    if (!__builtin_cpu_supports("fma")) return -1;
    shapes_fma(frames, Rs, ps, n, L, R, p);
    return 0;
}
