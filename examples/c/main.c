/* The generated msd estimator in a real-time loop.
 *
 * The plant is the paper's x'' + 2 x' + 3 x = f (B = 2, K = 3), driven by
 * f(t) = sin(t) from rest and integrated with the classical Runge-Kutta method at
 * 10 steps per sample.  Every millisecond the loop "reads" f and x and hands them
 * to algid_msd_update, one sample at a time, as a controller would; with every
 * estimate comes its numerical error (the relative error the arithmetic leaves, as
 * algid.estimate reports it).
 */
#include <math.h>
#include <stdio.h>

#include "algid_msd.h"

#define DT 1e-3          /* sampling step [s] */
#define DURATION 5.0     /* [s] */
#define SUBSTEPS 10      /* Runge-Kutta steps per sample */

static const double B_TRUE = 2.0, K_TRUE = 3.0;

static double force(double t) { return sin(t); }

/* x'' = f - B x' - K x as a first-order system in (x, v) */
static void derivative(double t, const double s[2], double d[2])
{
    d[0] = s[1];
    d[1] = force(t) - B_TRUE * s[1] - K_TRUE * s[0];
}

static void plant_step(double t, double s[2], double h)
{
    double k1[2], k2[2], k3[2], k4[2], tmp[2];
    int i;
    derivative(t, s, k1);
    for (i = 0; i < 2; ++i) tmp[i] = s[i] + 0.5 * h * k1[i];
    derivative(t + 0.5 * h, tmp, k2);
    for (i = 0; i < 2; ++i) tmp[i] = s[i] + 0.5 * h * k2[i];
    derivative(t + 0.5 * h, tmp, k3);
    for (i = 0; i < 2; ++i) tmp[i] = s[i] + h * k3[i];
    derivative(t + h, tmp, k4);
    for (i = 0; i < 2; ++i) s[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
}

int main(void)
{
    static double state[ALGID_MSD_STATE_DOUBLES];  /* no allocation */
    double plant[2] = {0.0, 0.0};                  /* x, x' */
    double theta[ALGID_MSD_N_PARAMETERS] = {0.0, 0.0};
    double error = 0.0;                             /* numerical error of theta */
    const long n = (long)(DURATION / DT + 0.5) + 1;
    long i;
    int j;

    if (algid_msd_init(state, DT, 0.0) != ALGID_MSD_OK) {
        fprintf(stderr, "algid_msd_init failed\n");
        return 1;
    }
    for (i = 0; i < n; ++i) {  /* one pass per sampling period */
        const double t = (double)i * DT;
        const double f = force(t), x = plant[0];  /* the "measurements" */
        algid_msd_update(state, &f, &x, 1, theta, &error);
        if (i % 1000 == 0 && i > 0) {
            printf("t = %4.1f s  B = %.12f  K = %.12f  numerical error %.1e\n", t,
                   theta[0], theta[1], error);
        }
        for (j = 0; j < SUBSTEPS; ++j) {  /* the plant until the next sample */
            plant_step(t + j * (DT / SUBSTEPS), plant, DT / SUBSTEPS);
        }
    }
    printf("B = %.12f\nK = %.12f\nnumerical error = %.1e\n", theta[0], theta[1], error);
    return 0;
}
