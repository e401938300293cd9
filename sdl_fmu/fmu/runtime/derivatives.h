/* Exact partial derivatives of an instance (CasADi forward and reverse mode), for
 * fmi2GetDirectionalDerivative, fmi3GetDirectionalDerivative and fmi3GetAdjointDerivative. */
#ifndef SDL_FMU_DERIVATIVES_H
#define SDL_FMU_DERIVATIVES_H

#include "instance.h"

/* sensitivity[i] = sum_j d unknown_i / d known_j * seed[j]   (seed: n_knowns, sensitivity: n_unknowns)
 * Unknowns: Real states, derivatives, outputs, locals and event indicators; knowns: Real states (not in
 * initialization, where the states are unknowns), Real inputs and Real parameters. Arguments that are not
 * allowed give STATUS_ERROR with a log message and change nothing. */
Status instance_directional_derivative(Instance *instance, const unsigned int unknowns[], size_t n_unknowns,
                                       const unsigned int knowns[], size_t n_knowns, const double seed[],
                                       double sensitivity[]);

/* sensitivity[j] = sum_i seed[i] * d unknown_i / d known_j   (seed: n_unknowns, sensitivity: n_knowns) */
Status instance_adjoint_derivative(Instance *instance, const unsigned int unknowns[], size_t n_unknowns,
                                   const unsigned int knowns[], size_t n_knowns, const double seed[],
                                   double sensitivity[]);

#endif
