/* Steps a moreau scene file from C and prints the state a host would read back.
 *
 *   cc -I include examples/c/step_scene.c -L target/release -lmoreau_c -o step_scene
 *   ./step_scene SCENE.toml [STEPS [THREADS [ORDERING [CRITERION [TIME_STEP [BLOCK_SWEEPS]]]]]]
 *
 * ORDERING and CRITERION replace the scene's (`worklist` and `velocity` suit a settled pile; `-`
 * keeps the scene's), TIME_STEP its time step in seconds (`-` keeps it), and BLOCK_SWEEPS its GPU
 * block sweeps (the steps here run on the CPU, which refuses the same out-of-range values).
 *
 * Exit status: 0 every step converged, 3 some did not, 1 an error (the message names it). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "moreau.h"

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: %s SCENE.toml [STEPS [THREADS [ORDERING [CRITERION [TIME_STEP [BLOCK_SWEEPS]]]]]]\n",
                argv[0]);
        return 2;
    }
    int steps = argc > 2 ? atoi(argv[2]) : 100;
    size_t threads = argc > 3 ? (size_t)atoi(argv[3]) : 0;
    MoreauSimulation *sim = NULL;
    if (moreau_simulation_from_scene(argv[1], &sim) != MOREAU_STATUS_OK ||
        moreau_simulation_set_device(sim, "cpu", threads) != MOREAU_STATUS_OK) {
        fprintf(stderr, "error: %s\n", moreau_last_error());
        moreau_simulation_free(sim);
        return 1;
    }
    if (argc > 4) {
        /* The scene's settings, with the names given replaced. */
        MoreauSolveOptions options;
        int ok = moreau_simulation_solve_options(sim, &options) == MOREAU_STATUS_OK;
        options.ordering = strcmp(argv[4], "-") ? argv[4] : NULL;
        options.criterion = argc > 5 && strcmp(argv[5], "-") ? argv[5] : NULL;
        if (argc > 7) {
            options.block_sweeps = (size_t)atoi(argv[7]);
        }
        if (!ok || moreau_simulation_set_solver(sim, &options) != MOREAU_STATUS_OK ||
            (argc > 6 && strcmp(argv[6], "-") && moreau_simulation_set_time_step(sim, atof(argv[6])) != MOREAU_STATUS_OK)) {
            fprintf(stderr, "error: %s\n", moreau_last_error());
            moreau_simulation_free(sim);
            return 1;
        }
    }
    /* What `moreau run` prints before the steps: the scene's notes, then its warnings and the start's. */
    for (size_t k = 0; *moreau_simulation_note(sim, k); k++) {
        fprintf(stderr, "note: %s\n", moreau_simulation_note(sim, k));
    }
    size_t warnings = 0;
    if (moreau_simulation_check(sim, &warnings) != MOREAU_STATUS_OK) {
        fprintf(stderr, "error: %s\n", moreau_last_error());
        moreau_simulation_free(sim);
        return 1;
    }
    for (size_t k = 0; k < warnings; k++) {
        fprintf(stderr, "warning: %s\n", moreau_simulation_warning(sim, k));
    }
    int unconverged = 0;
    MoreauStepReport report = {0};
    for (int k = 0; k < steps; k++) {
        if (moreau_simulation_step(sim, &report) != MOREAU_STATUS_OK) {
            fprintf(stderr, "error: %s\n", moreau_last_error());
            moreau_simulation_free(sim);
            return 1;
        }
        unconverged += !report.converged;
    }
    size_t bodies = moreau_simulation_body_count(sim);
    size_t count = moreau_simulation_contact_count(sim);
    double *xy = malloc(2 * bodies * sizeof(double));
    MoreauContact *contacts = malloc((count > 0 ? count : 1) * sizeof(MoreauContact));
    if (xy == NULL || contacts == NULL || moreau_simulation_copy_positions(sim, xy, 2 * bodies) != MOREAU_STATUS_OK ||
        moreau_simulation_copy_contacts(sim, contacts, count) != MOREAU_STATUS_OK) {
        fprintf(stderr, "error: %s\n", moreau_last_error());
        return 1;
    }
    double top = 0.0, normal_sum = 0.0;
    for (size_t k = 0; k < bodies; k++) {
        top = xy[2 * k + 1] > top ? xy[2 * k + 1] : top;
    }
    for (size_t c = 0; c < count; c++) {
        normal_sum += contacts[c].impulse[0];
    }
    printf("steps %zu time %.6f bodies %zu contacts %zu unconverged %d\n", report.step, moreau_simulation_time(sim),
           bodies, count, unconverged);
    printf("last step: iterations %zu error %.3e max_penetration %.3e velocity_scale %.9e top %.6f sum_rn %.9e\n",
           report.iterations, report.error, report.max_penetration, report.velocity_scale, top, normal_sum);
    printf("last step: stop %d warm_started %zu projected %zu kinetic_energy %.17g potential_energy %.17g "
           "dissipated_energy %.17g boundary_work %.17g\n",
           (int)report.stop, report.warm_started, report.projected, report.kinetic_energy, report.potential_energy,
           report.dissipated_energy, report.boundary_work);
    printf("last step: seconds %.6f detection %.6f solve %.6f projection %.6f\n", report.seconds,
           report.detection_seconds, report.solve_seconds, report.projection_seconds);
    free(xy);
    free(contacts);
    moreau_simulation_free(sim);
    return unconverged == 0 ? 0 : 3;
}
