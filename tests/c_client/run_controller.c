/* A real client of an exported controller header (tests/test_export.py compiles and runs it).
 *
 * Build: cc -std=c99 -I<folder of kctl.h> run_controller.c -o run_controller
 * Usage: run_controller inputs.txt
 * inputs.txt holds one sample per line, KCTL_NU numbers each. For every sample the program
 * steps the double and the float controller from zero state and prints one line:
 * KCTL_NY double outputs (%.17g) followed by KCTL_NY float outputs (%.9g).
 */
#include <stdio.h>

#include "kctl.h"

int main(int argc, char **argv)
{
    double x[KCTL_NX_ALLOC] = {0}, u[KCTL_NU], y[KCTL_NY];
    float xf[KCTL_NX_ALLOC] = {0}, uf[KCTL_NU], yf[KCTL_NY];
    FILE *in;
    int i;
    if (argc != 2 || (in = fopen(argv[1], "r")) == NULL) {
        fprintf(stderr, "usage: %s inputs.txt\n", argv[0]);
        return 2;
    }
    for (;;) {
        for (i = 0; i < KCTL_NU; ++i) {
            if (fscanf(in, "%lf", &u[i]) != 1) {
                fclose(in);
                return i == 0 ? 0 : 3; /* a partial last line is an error */
            }
            uf[i] = (float)u[i];
        }
        kctl_step(x, u, y);
        kctl_step_f(xf, uf, yf);
        for (i = 0; i < KCTL_NY; ++i) printf("%.17g ", y[i]);
        for (i = 0; i < KCTL_NY; ++i) printf("%.9g%s", (double)yf[i], i + 1 < KCTL_NY ? " " : "\n");
    }
}
