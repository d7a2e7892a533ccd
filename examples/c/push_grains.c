/* A blade pushes a bed of grains, driven from C: the host sets the blade's velocity, reads the
 * grains' load on it every step (the drag a coupled code would take), stops it, and lets the
 * grains come to rest (those pushed up the heap slide down it for about a second), when the loads
 * on the walls carry their weight.
 *
 *   cc -I include examples/c/push_grains.c -L target/release -lmoreau_c -o push_grains
 *   ./push_grains [PUSH_STEPS [REST_STEPS]]
 *
 * Exit status: 0 every step converged, 3 some did not, 1 an error (the message names it). */
#include <stdio.h>
#include <stdlib.h>

#include "moreau.h"

enum { BLADE = 3 };

static int fail(MoreauWorld *world, MoreauSimulation *sim) {
    fprintf(stderr, "error: %s\n", moreau_last_error());
    moreau_simulation_free(sim);
    moreau_world_free(world);
    return 1;
}

int main(int argc, char **argv) {
    int push_steps = argc > 1 ? atoi(argv[1]) : 300, rest_steps = argc > 2 ? atoi(argv[2]) : 1200;
    const char *names[] = {"sand"};
    const double densities[] = {2500.0};
    MoreauWorldSettings settings = moreau_world_settings_default();
    settings.moving_walls = true;
    settings.law.friction = 0.4;
    MoreauWorld *world = NULL;
    MoreauSimulation *sim = NULL;
    if (moreau_world_new(names, densities, 1, &settings, &world) != MOREAU_STATUS_OK) {
        return fail(world, sim);
    }
    /* A floor and two sides (walls 0-2), then the blade (wall 3), standing on the floor. */
    const double walls[4][4] = {{-1.0, 0.0, 1.0, 0.0}, {-1.0, 0.0, -1.0, 1.0}, {1.0, 0.0, 1.0, 1.0}, {-0.8, 0.0, -0.8, 0.4}};
    int ok = 1;
    for (int w = 0; ok && w < 4; w++) {
        ok = moreau_world_add_wall(world, walls[w][0], walls[w][1], walls[w][2], walls[w][3], "sand", 0.0, 0.0, NULL) ==
             MOREAU_STATUS_OK;
    }
    for (int k = 0; ok && k < 40; k++) {
        double x = -0.7 + 0.1 * (k % 10) + 0.02 * (k / 10 % 2), y = 0.04 + 0.081 * (k / 10);
        ok = moreau_world_add_disk(world, x, y, 0.04, "sand", NULL, NULL) == MOREAU_STATUS_OK;
    }
    if (!ok || moreau_simulation_new(world, 1e-3, NULL, &sim) != MOREAU_STATUS_OK ||
        moreau_simulation_set_device(sim, "cpu", 1) != MOREAU_STATUS_OK ||
        moreau_simulation_set_wall_motion(sim, BLADE, 0.5, 0.0, 0.0) != MOREAU_STATUS_OK) {
        return fail(world, sim);
    }
    moreau_world_free(world);
    world = NULL;
    size_t wall_count = moreau_simulation_wall_count(sim), bodies = moreau_simulation_body_count(sim);
    double *loads = malloc(3 * (bodies > wall_count ? bodies : wall_count) * sizeof(double));
    double drag = 0.0, frames[3 * 4];
    int unconverged = 0;
    MoreauStepReport report = {0};
    for (int k = 0; k < push_steps + rest_steps; k++) {
        if (k == push_steps && moreau_simulation_set_wall_motion(sim, BLADE, 0.0, 0.0, 0.0) != MOREAU_STATUS_OK) {
            return fail(world, sim);
        }
        if (loads == NULL || moreau_simulation_step(sim, &report) != MOREAU_STATUS_OK ||
            moreau_simulation_copy_wall_loads(sim, loads, 3 * wall_count) != MOREAU_STATUS_OK) {
            return fail(world, sim);
        }
        unconverged += !report.converged;
        /* The grains push the blade back (-x): the drag is the opposite of its load. */
        drag -= k < push_steps ? loads[3 * BLADE] / push_steps : 0.0;
    }
    double sum_fx = 0.0, sum_fy = 0.0;
    for (size_t w = 0; w < wall_count; w++) {
        sum_fx += loads[3 * w];
        sum_fy += loads[3 * w + 1];
    }
    if (moreau_simulation_copy_walls(sim, frames, sizeof frames / sizeof *frames) != MOREAU_STATUS_OK ||
        moreau_simulation_copy_body_loads(sim, loads, 3 * bodies) != MOREAU_STATUS_OK) {
        return fail(world, sim);
    }
    double grains_fy = 0.0;
    for (size_t k = 0; k < bodies; k++) {
        grains_fy += loads[3 * k + 1];
    }
    printf("steps %zu bodies %zu walls %zu unconverged %d blade_x %.12f\n", report.step, bodies, wall_count,
           unconverged, frames[3 * BLADE]);
    printf("mean_drag %.17g walls_fx %.17g walls_fy %.17g grains_fy %.17g\n", drag, sum_fx, sum_fy, grains_fy);
    free(loads);
    moreau_simulation_free(sim);
    return unconverged == 0 ? 0 : 3;
}
