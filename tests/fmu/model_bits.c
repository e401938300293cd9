/* Evaluates a model's six functions (model.h) on pseudo-random (x, d, u, p) and prints a hash of every result's
 * bits, the number of values and the number of distinct values among the first case's: built by
 * test_fmu_binaries.py against one model object compiled at several optimisation levels. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "model.h"

#define SIZE 4096

static uint64_t state = 88172645463325252ull;

static double uniform(void) { /* xorshift64: the same sequence on every build */
    state ^= state << 13;
    state ^= state >> 7;
    state ^= state << 17;
    return (double)(state >> 11) * (1.0 / 9007199254740992.0);
}

static double x[SIZE], d[SIZE], u[SIZE], p[SIZE], results[2][SIZE], w[1 << 20];
static casadi_int_t iw[1 << 16];

int main(int argc, char **argv) {
    const ModelInfo *m = &model_info;
    const ModelFunction *functions[6] = {&m->derivatives, &m->jacobian, &m->outputs, &m->event_indicators,
                                         &m->discrete_update, &m->initial_state};
    const double *arg[256] = {x, d, u, p};
    double *res[256] = {results[0], results[1]};
    int cases = argc > 1 ? atoi(argv[1]) : 100;
    uint64_t hash = 1469598103934665603ull, values = 0;
    for (int j = 0; j < 6; j++) {
        casadi_int_t sz_arg, sz_res, sz_iw, sz_w;
        functions[j]->work(&sz_arg, &sz_res, &sz_iw, &sz_w);
        if (sz_arg > 256 || sz_res > 256 || sz_iw > (1 << 16) || sz_w > (1 << 20)) return 2;
    }
    if (m->nx > SIZE || m->nd > SIZE || m->nu > SIZE || m->np > SIZE || m->nx * m->nx > SIZE) return 2;
    for (int k = 0; k < cases; k++) {
        memcpy(u, m->input_start, sizeof(double) * (size_t)m->nu);
        memcpy(p, m->parameter_start, sizeof(double) * (size_t)m->np);
        for (int i = 0; i < m->nu; i++) u[i] += (uniform() - 0.5) * (1.0 + u[i]);
        if (m->model_exchange_parameter >= 0) p[m->model_exchange_parameter] = (double)(k % 2);
        memset(x, 0, sizeof x);
        memset(d, 0, sizeof d);
        if (m->initial_state.eval(arg, res, iw, w, 0)) return 3;
        memcpy(x, results[0], sizeof(double) * (size_t)m->nx);
        memcpy(d, results[1], sizeof(double) * (size_t)m->nd);
        for (int i = 0; i < m->nx; i++) x[i] += (uniform() - 0.5) * 2.0 * m->state_nominal[i] * (1.0 + 10.0 * uniform());
        for (int i = 0; i < m->nd; i++)
            if (uniform() < 0.3) d[i] = (double)(int)(uniform() * 3.0);
        for (int j = 0; j < 6; j++) {
            for (int i = 0; i < SIZE; i++) results[0][i] = results[1][i] = 0.0;
            if (functions[j]->eval(arg, res, iw, w, 0)) return 3;
            for (int r = 0; r < 2; r++)
                for (int i = 0; i < SIZE; i++) {
                    uint64_t bits;
                    memcpy(&bits, &results[r][i], sizeof bits);
                    hash = (hash ^ bits) * 1099511628211ull; /* FNV-1a over every result, in order */
                    values += results[r][i] != 0.0;
                }
        }
    }
    printf("%d cases, %llu nonzero values, hash %016llx\n", cases, (unsigned long long)values,
           (unsigned long long)hash);
    return 0;
}
