/* Solves a Siconos fc2d problem file with moreau's C interface and prints what the solve did.
 *
 *   cc -I include examples/c/solve_file.c -L target/release -lmoreau_c -o solve_file
 *   ./solve_file PROBLEM.dat [TOL [SOLVER [ANDERSON [DEVICE [OMEGA]]]]]
 *
 * PROBLEM.dat may be deposit:N instead, the first step of N disks deposited in a box at
 * friction 0.3, seed 7 (moreau_problem_deposit, as `moreau generate deposit`).
 *
 * Exit status: 0 converged, 3 not converged, 1 an error (the message names it). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "moreau.h"

static int report_error(const char *what) {
    fprintf(stderr, "error: %s: %s\n", what, moreau_last_error());
    return 1;
}

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: %s PROBLEM.dat [TOL [SOLVER [ANDERSON [DEVICE [OMEGA]]]]]\n", argv[0]);
        return 2;
    }
    if (moreau_abi_version() != MOREAU_ABI_VERSION) {
        fprintf(stderr, "error: compiled against moreau.h of ABI %d, running with a library of ABI %u\n",
                MOREAU_ABI_VERSION, moreau_abi_version());
        return 1;
    }
    MoreauProblem *problem = NULL;
    if (strncmp(argv[1], "deposit:", 8) == 0) {
        if (moreau_problem_deposit((size_t)strtoul(argv[1] + 8, NULL, 10), 0.3, 7, &problem) != MOREAU_STATUS_OK) {
            return report_error("building the deposit");
        }
    } else if (moreau_problem_read_fc2d(argv[1], &problem) != MOREAU_STATUS_OK) {
        return report_error("reading the problem");
    }
    MoreauSolveOptions options = moreau_solve_options_default();
    options.tol = argc > 2 ? atof(argv[2]) : 1e-8;
    options.max_iter = 100000;
    if (argc > 3) {
        options.solver = argv[3];
    }
    if (argc > 4) {
        options.anderson = (size_t)strtoul(argv[4], NULL, 10);
    }
    if (argc > 5) {
        options.device = argv[5];
    }
    if (argc > 6) {
        options.omega = atof(argv[6]);
    }
    MoreauSolution *solution = NULL;
    if (moreau_solve(problem, &options, NULL, &solution) != MOREAU_STATUS_OK) {
        moreau_problem_free(problem);
        return report_error("solving");
    }
    MoreauSolveSummary summary;
    moreau_solution_summary(solution, &summary);
    size_t n = moreau_problem_contacts(problem);
    double *r = malloc(2 * n * sizeof(double));
    double normal_sum = 0.0;
    if (r != NULL && moreau_solution_copy_r(solution, r, 2 * n) == MOREAU_STATUS_OK) {
        for (size_t k = 0; k < n; k++) {
            normal_sum += r[2 * k];
        }
    }
    printf("contacts %zu converged %d iterations %zu gpu_iterations %zu error %.3e sum_rn %.9e "
           "velocity_error %.17g stop_code %d\n",
           n, summary.converged, summary.iterations, summary.gpu_iterations, summary.error, normal_sum,
           summary.velocity_error, (int)summary.stop);
    printf("stop: %s\ndevice: %s\n", moreau_solution_stop_reason(solution), moreau_solution_device(solution));
    free(r);
    moreau_solution_free(solution);
    moreau_problem_free(problem);
    return summary.converged ? 0 : 3;
}
