/* Every node's transform in the world at the given times, as ufbx (https://github.com/ufbx/ufbx, MIT or public
 * domain) evaluates an FBX file: its first animation stack, all its layers, no unit or axis conversion.
 * Built and run by benchmarks/fbx_against_ufbx.py:  world_transforms FILE SECONDS...
 * Prints "FPS <rate>", then per time and node "T <seconds> <name>|<m00 m10 m20 m01 m11 m21 m02 m12 m22 m03 m13 m23>"
 * (the 3x4 matrix column by column), or "ERROR <why>". */
#include "ufbx.h"
#include <stdio.h>
#include <stdlib.h>
int main(int argc, char **argv) {
    ufbx_load_opts opts = { 0 };
    ufbx_error err;
    ufbx_scene *scene = ufbx_load_file(argv[1], &opts, &err);
    if (!scene) { printf("ERROR %s\n", err.description.data); return 1; }
    printf("FPS %f\n", scene->settings.frames_per_second);
    for (int a = 2; a < argc; a++) {
        double t = atof(argv[a]);
        ufbx_scene *state = ufbx_evaluate_scene(scene, scene->anim, t, NULL, NULL);
        if (!state) { printf("ERROR eval\n"); return 1; }
        for (size_t i = 0; i < state->nodes.count; i++) {
            ufbx_node *n = state->nodes.data[i];
            if (n->is_root) continue;
            ufbx_matrix m = n->node_to_world;
            printf("T %f %s|%.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g\n", t, n->name.data,
                   m.m00, m.m10, m.m20, m.m01, m.m11, m.m21, m.m02, m.m12, m.m22, m.m03, m.m13, m.m23);
        }
        ufbx_free_scene(state);
    }
    ufbx_free_scene(scene);
    return 0;
}
