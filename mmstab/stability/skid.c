/* The skid-steer model's Newton solve (skid.py's skid_twist loop), one row at a time.
 *
 * The same operations as the NumPy loop: the regularised Coulomb (or Wong-Chiang) forces of
 * the belts' samples and their Jacobian, a Newton step from a 3x3 solve (J + 1e-12 I),
 * a step length halved while the squared residual grows (at most `backtracks` times), a
 * continuation over the regularisations `eps`. NumPy iterates every row until the last has
 * converged; here each row stops at its own convergence (the twins agree to round-off:
 * tests/stability/test_skid_kernel.py). Rows that do not hold (outside the friction cone or
 * the belts) are left NaN, rows whose belts stand are left 0 (skid.py sets both so).
 */
#include <math.h>
#include <string.h>

/* Forces and yaw moment per unit weight / mu (F, 3) and their Jacobian (J, 3x3, row-major;
 * NULL: not wanted) of one row at twist z. */
static void forces(long S, const double *x, const double *y, const long *side, double length,
                   const double *loads, const double *u, const double *z, double eps,
                   const double *tau, double shear, double *F, double *J) {
    double f0 = 0.0, f1 = 0.0, f2 = 0.0;
    double j[9];
    memset(j, 0, sizeof j);
    for (long s = 0; s < S; ++s) {
        double n = loads[s];
        if (n == 0.0) continue; /* an unloaded sample adds nothing (NumPy adds its zeros) */
        double sx = z[0] - z[2] * y[s] - u[side[s]];
        double sy = z[1] + z[2] * x[s];
        double sigma = sqrt(sx * sx + sy * sy + eps * eps);
        double phi = 1.0, c = 0.0;
        if (shear > 0.0 && isfinite(tau[s])) {
            double decay = exp(-sigma * tau[s] / shear);
            phi = 1.0 - decay;
            c = tau[s] / shear * decay;
        }
        double fx = -n * phi * sx / sigma, fy = -n * phi * sy / sigma;
        f0 += fx;
        f1 += fy;
        f2 += x[s] * fy - y[s] * fx;
        if (J) {
            double s2 = sigma * sigma, s3 = s2 * sigma;
            double dxx = -n * (phi * (1.0 / sigma - sx * sx / s3) + c * sx * sx / s2);
            double dyy = -n * (phi * (1.0 / sigma - sy * sy / s3) + c * sy * sy / s2);
            double dxy = -n * (-phi * sx * sy / s3 + c * sx * sy / s2);
            /* d s / d z = [[1, 0, -y], [0, 1, x]] */
            double d0[3] = {1.0, 0.0, -y[s]}, d1[3] = {0.0, 1.0, x[s]};
            for (int k = 0; k < 3; ++k) {
                double dfx = dxx * d0[k] + dxy * d1[k];
                double dfy = dxy * d0[k] + dyy * d1[k];
                j[k] += dfx;
                j[3 + k] += dfy;
                j[6 + k] += x[s] * dfy - y[s] * dfx;
            }
        }
    }
    F[0] = f0;
    F[1] = f1;
    F[2] = f2 / length;
    if (J) {
        for (int k = 0; k < 6; ++k) J[k] = j[k];
        for (int k = 6; k < 9; ++k) J[k] = j[k] / length;
    }
}

/* Solve A x = b (3x3, row-major, A and b overwritten) by elimination with partial pivoting;
 * x NaN where a pivot is 0. */
static void solve3(double *A, double *b, double *out) {
    int p[3] = {0, 1, 2};
    for (int c = 0; c < 3; ++c) {
        int best = c;
        for (int r = c + 1; r < 3; ++r)
            if (fabs(A[3 * p[r] + c]) > fabs(A[3 * p[best] + c])) best = r;
        int t = p[c];
        p[c] = p[best];
        p[best] = t;
        double piv = A[3 * p[c] + c];
        if (piv == 0.0) {
            out[0] = out[1] = out[2] = NAN;
            return;
        }
        for (int r = c + 1; r < 3; ++r) {
            double m = A[3 * p[r] + c] / piv;
            for (int k = c; k < 3; ++k) A[3 * p[r] + k] -= m * A[3 * p[c] + k];
            b[p[r]] -= m * b[p[c]];
        }
    }
    for (int c = 2; c >= 0; --c) {
        double v = b[p[c]];
        for (int k = c + 1; k < 3; ++k) v -= A[3 * p[c] + k] * out[k];
        out[c] = v / A[3 * p[c] + c];
    }
}

static double residual2(const double *F, const double *load) {
    double r = 0.0;
    for (int k = 0; k < 3; ++k) r += (F[k] + load[k]) * (F[k] + load[k]);
    return r;
}

/* The steady twists of N rows (skid.py's skid_twist, after its set-up).
 *
 * x, y, side: the belts' S samples; length: the contact length [m]. Per row: loads (N, S),
 * belts u (N, 2), twist z (N, 3: the start in, the answer out, in units of the belt speed),
 * gravity's load (N, 3), contact times tau (N, S; inf: forever), holds and moving (N);
 * shear: K [m] (0: Coulomb); eps (neps): the continuation; tol: Newton's residual;
 * iterations, backtracks: its limits; final_tol: the residual at eps[neps - 1] a row must
 * reach to count as converged (out, N). Returns 0. */
int mmstab_skid_twist(long N, long S, const double *x, const double *y, const long *side,
                      double length, const double *loads, const double *u, double *z,
                      const double *load, const double *tau, const unsigned char *holds,
                      const unsigned char *moving, double shear, const double *eps, long neps,
                      double tol, long iterations, long backtracks, double final_tol,
                      unsigned char *converged) {
    for (long i = 0; i < N; ++i) {
        const double *ni = loads + i * S, *ui = u + 2 * i, *li = load + 3 * i,
                     *ti = tau + i * S;
        double *zi = z + 3 * i;
        converged[i] = 0;
        if (!holds[i]) {
            zi[0] = zi[1] = zi[2] = NAN;
            continue;
        }
        if (!moving[i]) {
            zi[0] = zi[1] = zi[2] = 0.0;
            converged[i] = 1;
            continue;
        }
        for (long e = 0; e < neps; ++e) {
            for (long it = 0; it < iterations; ++it) {
                double F[3], J[9], r[3], step[3];
                forces(S, x, y, side, length, ni, ui, zi, eps[e], ti, shear, F, J);
                for (int k = 0; k < 3; ++k) r[k] = F[k] + li[k];
                if (fabs(r[0]) < tol && fabs(r[1]) < tol && fabs(r[2]) < tol) break;
                if (!(isfinite(zi[0]) && isfinite(zi[1]) && isfinite(zi[2]))) break;
                for (int k = 0; k < 3; ++k) {
                    J[4 * k] += 1e-12;
                    r[k] = -r[k];
                }
                solve3(J, r, step);
                double r0 = residual2(F, li), alpha = 1.0;
                for (long b = 0; b < backtracks; ++b) {
                    double moved[3], Fm[3];
                    for (int k = 0; k < 3; ++k) moved[k] = zi[k] + alpha * step[k];
                    forces(S, x, y, side, length, ni, ui, moved, eps[e], ti, shear, Fm, NULL);
                    if (!(residual2(Fm, li) > r0)) break;
                    alpha /= 2.0;
                }
                for (int k = 0; k < 3; ++k) zi[k] += alpha * step[k];
            }
        }
        double F[3];
        forces(S, x, y, side, length, ni, ui, zi, eps[neps - 1], ti, shear, F, NULL);
        converged[i] = fabs(F[0] + li[0]) < final_tol && fabs(F[1] + li[1]) < final_tol &&
                       fabs(F[2] + li[2]) < final_tol;
    }
    return 0;
}
