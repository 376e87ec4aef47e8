/* The climb limit's rolls of the front wheels over the ground ahead (mmstab.stability.climb's
 * _worst_contact, whose NumPy path is its twin: the same sin θ for every roll it computes).
 *
 * zpad (2, P) row-major: the two tracks' ground samples [m], padded with -inf; roll k's window
 * is zpad[t, k .. k + W - 1], lift (W,) the wheel's circle over it (-inf outside the radius);
 * at (2, R): the rolls to compute. Each computed roll: the wheel's centre rests on the highest
 * sample + lift (the first of equals; a NaN sample, the first, is NumPy's argmax), touching
 * that sample; sin θ = (top - touch) / r clipped to [-1, 1], or 1 where the centre stays at
 * or below r (on the plane). Samples at or below the plane (z <= 0, -inf) lift the centre at
 * most to r, so they never decide a roll above it and are passed over. Out: sin_roll (2, R),
 * left as given where not computed. Returns 0.
 */
#include <math.h>

int mmstab_climb_rolls(long P, long W, const double *zpad, const double *lift, long R,
                       const unsigned char *at, double r, double *sin_roll) {
    for (long t = 0; t < 2; ++t) {
        const double *z = zpad + t * P;
        for (long k = 0; k < R; ++k) {
            if (!at[t * R + k]) continue;
            double top = -INFINITY, touch = 0.0;
            int found = 0;
            for (long j = 0; j < W; ++j) {
                double zj = z[k + j];
                if (zj <= 0.0) continue; /* at or below the plane: the centre stays <= r */
                double c = zj + lift[j];
                if (isnan(c)) { /* NumPy's argmax: the first NaN */
                    top = NAN;
                    touch = zj;
                    found = 1;
                    break;
                }
                if (!found || c > top) {
                    top = c;
                    touch = zj;
                    found = 1;
                }
            }
            double s;
            if (!found || top <= r) {
                s = 1.0;
            } else {
                s = (top - touch) / r;
                s = s < -1.0 ? -1.0 : (s > 1.0 ? 1.0 : s);
            }
            if (isnan(top)) s = NAN;
            sin_roll[t * R + k] = s;
        }
    }
    return 0;
}
