/* Builds a world in code from C, without a scene file, and steps it: two materials with their own
 * contact law, a box of three walls, three columns of disks, a polygon lid set spinning after the
 * first step, a dimer (a clump of two disks), the disks of a grains file when one is given, and a
 * block driven along the floor as a piston is.
 *
 *   cc -I include examples/c/build_world.c -L target/release -lmoreau_c -o build_world
 *   ./build_world [STEPS [GRAINS.csv]]
 *
 * A scene file that describes the same world steps to the same bits (capi/tests/c_programs.rs).
 * Exit status: 0 every step converged, 3 some did not, 1 an error (the message names it). */
#include <stdio.h>
#include <stdlib.h>

#include "moreau.h"

static int fail(MoreauWorld *world, MoreauSimulation *sim) {
    fprintf(stderr, "error: %s\n", moreau_last_error());
    moreau_simulation_free(sim);
    moreau_world_free(world);
    return 1;
}

int main(int argc, char **argv) {
    int steps = argc > 1 ? atoi(argv[1]) : 100;
    const char *names[] = {"grain", "steel"};
    const double densities[] = {2500.0, 7800.0};
    MoreauWorldSettings settings = moreau_world_settings_default();
    settings.rotation = true;
    settings.law.friction = 0.5;
    MoreauWorld *world = NULL;
    MoreauSimulation *sim = NULL;
    if (moreau_world_new(names, densities, 2, &settings, &world) != MOREAU_STATUS_OK) {
        return fail(world, sim);
    }
    MoreauLaw on_steel = {.friction = 0.3, .restitution = 0.0, .cohesion = 0.0, .rolling_resistance = 0.0};
    int ok = moreau_world_set_interaction(world, "grain", "steel", on_steel) == MOREAU_STATUS_OK;
    ok = ok && moreau_world_add_wall(world, -0.5, 0.0, 0.5, 0.0, "steel", 0.0, 0.0, NULL) == MOREAU_STATUS_OK;
    ok = ok && moreau_world_add_wall(world, -0.5, 0.0, -0.5, 1.0, "steel", 0.0, 0.0, NULL) == MOREAU_STATUS_OK;
    ok = ok && moreau_world_add_wall(world, 0.5, 0.0, 0.5, 1.0, "steel", 0.0, 0.0, NULL) == MOREAU_STATUS_OK;
    for (int k = 0; ok && k < 15; k++) {
        double x = 0.1 * (k % 3 - 1) + 0.01 * (k / 3 % 2), y = 0.05 + 0.1 * (k / 3);
        /* The last disk is thrown sideways, spinning; the others start at rest (NULL). */
        MoreauMotion thrown = {.vx = -0.3, .vy = 0.0, .spin = 2.0, .fixed = false};
        ok = moreau_world_add_disk(world, x, y, 0.04, "grain", k == 14 ? &thrown : NULL, NULL) == MOREAU_STATUS_OK;
    }
    const double lid[] = {-0.15, -0.02, 0.15, -0.02, 0.15, 0.02, -0.15, 0.02};
    size_t lid_body = 0;
    ok = ok && moreau_world_add_polygon(world, 0.0, 0.6, lid, 4, 0.1, "steel", NULL, &lid_body) == MOREAU_STATUS_OK;
    /* A dimer: two overlapping disks (x, y, r) as one rigid grain, turned by 0.3 rad. */
    const double dimer[] = {-0.03, 0.0, 0.04, 0.03, 0.0, 0.04};
    ok = ok && moreau_world_add_clump(world, 0.3, 0.4, dimer, 2, 0.3, "grain", NULL, NULL) == MOREAU_STATUS_OK;
    /* A steel block driven along the floor: held along x at -0.05 m/s whatever friction does,
     * pressed down by 20 N, its angle kept, 1 kg instead of its density's 25 kg. */
    const double block[] = {-0.04, -0.02, 0.04, -0.02, 0.04, 0.02, -0.04, 0.02};
    MoreauMotion driven = {.vx = -0.05, .force_y = -20.0, .lock_rotation = true, .mass = 1.0, .hold_x = true};
    size_t block_body = 0;
    ok = ok && moreau_world_add_polygon(world, 0.44, 0.02, block, 4, 0.0, "steel", &driven, &block_body) == MOREAU_STATUS_OK;
    size_t rows = 0, first_row_body = 0;
    if (ok && argc > 2) {
        ok = moreau_world_add_grains(world, argv[2], "grain", "auto", &rows) == MOREAU_STATUS_OK;
        size_t *bodies = malloc((rows > 0 ? rows : 1) * sizeof(size_t));
        ok = ok && bodies != NULL && moreau_world_copy_grain_bodies(world, bodies, rows) == MOREAU_STATUS_OK;
        first_row_body = ok && rows > 0 ? bodies[0] : 0;
        free(bodies);
    }
    /* The simulation copies the world: the world is freed at once. One thread: the reference path. */
    if (!ok || moreau_simulation_new(world, 1e-3, NULL, &sim) != MOREAU_STATUS_OK ||
        moreau_simulation_set_device(sim, "cpu", 1) != MOREAU_STATUS_OK) {
        return fail(world, sim);
    }
    moreau_world_free(world);
    world = NULL;
    int unconverged = 0;
    MoreauStepReport report = {0};
    for (int k = 0; k < steps; k++) {
        if (moreau_simulation_step(sim, &report) != MOREAU_STATUS_OK ||
            (k == 0 && moreau_simulation_set_spin(sim, lid_body, 0.5) != MOREAU_STATUS_OK)) {
            return fail(world, sim);
        }
        unconverged += !report.converged;
    }
    size_t bodies = moreau_simulation_body_count(sim);
    double *xy = malloc(2 * bodies * sizeof(double)), *angles = malloc(bodies * sizeof(double));
    if (xy == NULL || angles == NULL || moreau_simulation_copy_positions(sim, xy, 2 * bodies) != MOREAU_STATUS_OK ||
        moreau_simulation_copy_rotations(sim, angles, NULL, bodies) != MOREAU_STATUS_OK) {
        return fail(world, sim);
    }
    /* Summed in body order, as the test sums the scene's: equal bits or a different run. */
    double sum = 0.0;
    for (size_t k = 0; k < bodies; k++) {
        sum += xy[2 * k] + xy[2 * k + 1] + angles[k];
    }
    printf("steps %zu bodies %zu lid %zu rows %zu first_row_body %zu contacts %zu unconverged %d\n", report.step,
           bodies, lid_body, rows, first_row_body, moreau_simulation_contact_count(sim), unconverged);
    printf("lid %.6f %.6f angle %.6f sum %.17g\n", xy[2 * lid_body], xy[2 * lid_body + 1], angles[lid_body], sum);
    printf("block %zu block_x %.17g block_y %.17g block_angle %.17g\n", block_body, xy[2 * block_body], xy[2 * block_body + 1],
           angles[block_body]);
    free(xy);
    free(angles);
    moreau_simulation_free(sim);
    return unconverged == 0 ? 0 : 3;
}
