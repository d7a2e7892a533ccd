/* Steps a moreau scene from C, keeps a checkpoint, goes on from it in a second simulation and
 * checks that both runs agree to the bit, then pours a disk in and prints the measures.
 *
 *   cc -I include examples/c/restart_scene.c -L target/release -lmoreau_c -o restart_scene
 *   ./restart_scene SCENE.toml STEPS CHECKPOINT.json MATERIAL
 *
 * The checkpoint is stamped with the scene file, so `moreau run SCENE --restart CHECKPOINT.json`
 * goes on from it too. Exit status: 0 the runs agree, 3 they do not, 1 an error (named). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "moreau.h"

static int fail(MoreauSimulation *a, MoreauSimulation *b) {
    fprintf(stderr, "error: %s\n", moreau_last_error());
    moreau_simulation_free(a);
    moreau_simulation_free(b);
    return 1;
}

static int steps(MoreauSimulation *sim, int n) {
    for (int k = 0; k < n; k++) {
        if (moreau_simulation_step(sim, NULL) != MOREAU_STATUS_OK) {
            return 0;
        }
    }
    return 1;
}

static void print_measures(const char *what, const MoreauMeasures *m) {
    printf("%s: packing_fraction %.17g coordination %.17g rattlers %zu stress_yy %.17g anisotropy %.17g "
           "neighbours %.17g\n",
           what, m->packing_fraction, m->coordination, m->rattlers, m->stress_yy, m->anisotropy, m->neighbours);
}

int main(int argc, char **argv) {
    if (argc < 5) {
        fprintf(stderr, "usage: %s SCENE.toml STEPS CHECKPOINT.json MATERIAL\n", argv[0]);
        return 2;
    }
    const char *scene = argv[1], *checkpoint = argv[3], *material = argv[4];
    int n = atoi(argv[2]);
    MoreauSimulation *first = NULL, *second = NULL;
    if (moreau_simulation_from_scene(scene, &first) != MOREAU_STATUS_OK ||
        moreau_simulation_set_device(first, "cpu", 1) != MOREAU_STATUS_OK || !steps(first, n) ||
        moreau_simulation_write_checkpoint(first, checkpoint, scene) != MOREAU_STATUS_OK || !steps(first, 10)) {
        return fail(first, second);
    }
    /* A second simulation of the same scene, gone back to the checkpoint. */
    if (moreau_simulation_from_scene(scene, &second) != MOREAU_STATUS_OK ||
        moreau_simulation_set_device(second, "cpu", 1) != MOREAU_STATUS_OK ||
        moreau_simulation_restore(second, checkpoint, scene) != MOREAU_STATUS_OK || !steps(second, 10)) {
        return fail(first, second);
    }
    MoreauMeasures straight, restarted;
    if (moreau_simulation_measures(first, &straight) != MOREAU_STATUS_OK ||
        moreau_simulation_measures(second, &restarted) != MOREAU_STATUS_OK) {
        return fail(first, second);
    }
    print_measures("straight", &straight);
    print_measures("restarted", &restarted);
    int same = memcmp(&straight, &restarted, sizeof straight) == 0;
    /* A disk poured in above the highest grain, falling. */
    size_t bodies = moreau_simulation_body_count(second), added = 0;
    double *xy = malloc(2 * bodies * sizeof(double));
    if (xy == NULL || moreau_simulation_copy_positions(second, xy, 2 * bodies) != MOREAU_STATUS_OK) {
        free(xy);
        return fail(first, second);
    }
    double top = 0.0, x = 0.0;
    for (size_t k = 0; k < bodies; k++) {
        if (xy[2 * k + 1] > top) {
            top = xy[2 * k + 1];
            x = xy[2 * k];
        }
    }
    free(xy);
    if (moreau_simulation_add_disk(second, x, top + 0.05, 0.01, material, 0.0, -0.5, &added) != MOREAU_STATUS_OK ||
        !steps(second, 5)) {
        return fail(first, second);
    }
    printf("added body %zu of %zu at x %.17g y %.17g; restart %s\n", added, moreau_simulation_body_count(second), x,
           top + 0.05, same ? "identical" : "DIFFERENT");
    moreau_simulation_free(first);
    moreau_simulation_free(second);
    return same ? 0 : 3;
}
