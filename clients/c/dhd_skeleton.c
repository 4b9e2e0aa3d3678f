/*
 * dhd_skeleton.c: where the vps bridge calls go in a Force Dimension DHD loop (omega.x, sigma.x,
 * delta.x, and Novint Falcon through the same SDK). A commented skeleton, not tested here: it
 * compiles against the real SDK only when VPS_WITH_DHD is defined, e.g.
 *
 *   gcc -std=c99 -O2 -DVPS_WITH_DHD -I$FD_SDK/include -o dhd_bridge dhd_skeleton.c \
 *       -L$FD_SDK/lib/release/lin-x86_64-gcc -ldhd -lpthread -lusb-1.0 -lm
 *   vps run --device bridge:127.0.0.1:7700 --map-scale 5 --seconds 600 &
 *   ./dhd_bridge 127.0.0.1:7700
 *
 * Without that define it builds, one file at a time (each has its own main; example.c too), a
 * stub that says so: `gcc -std=c99 -O2 -o STUB FILE.c -lm` never needs the SDK.
 *
 * Units: DHD already speaks SI (m, m/s, rad/s, N, N.m), as vps does.
 */
#define _POSIX_C_SOURCE 200809L
#include "vps_skeleton.h"

#ifdef VPS_WITH_DHD
#include <dhdc.h>

int main(int argc, char **argv) {
    vps_bridge bridge;
    vps_wrench wrench;
    double last_wrench_time = -1.0, next_tick, now;
    double matrix[3][3];
    vps_pose pose;
    int i, status;
    if ((status = vps_skeleton_open(&bridge, argc, argv)) != 0) return status;
    if (dhdOpen() < 0) {
        fprintf(stderr, "dhdOpen: %s\n", dhdErrorGetLastStr());
        return 1;
    }
    dhdEnableForce(DHD_ON);
    next_tick = dhdGetTime();
    while (!dhdKbHit()) {
        /* 1. Read the handle (m, rotation matrix, m/s, rad/s). */
        dhdGetPosition(&pose.position[0], &pose.position[1], &pose.position[2]);
        dhdGetOrientationFrame(matrix);
        dhdGetLinearVelocity(&pose.linear_velocity[0], &pose.linear_velocity[1],
                             &pose.linear_velocity[2]);
        dhdGetAngularVelocityRad(&pose.angular_velocity[0], &pose.angular_velocity[1],
                                 &pose.angular_velocity[2]);
        if (vps_quat_from_matrix(&matrix[0][0], pose.orientation) != 0) {
            pose.orientation[0] = pose.orientation[1] = pose.orientation[2] = 0.0;
            pose.orientation[3] = 1.0;
        }

        /* 2. Send it once per millisecond; button 0 is the clutch. */
        now = dhdGetTime();
        if (now >= next_tick) {
            next_tick += 1e-3;
            vps_bridge_send_pose(&bridge, &pose, dhdGetButton(0) ? VPS_FLAG_CLUTCH : 0);
        }

        /* 3. Take the newest wrench without blocking. */
        if (vps_bridge_recv_latest(&bridge, &wrench) > 0) last_wrench_time = now;

        /* 4. Apply it, or zero after 20 ms without one. The DHD loop may run faster than 1 kHz:
         *    the last wrench is held between replies. */
        if (last_wrench_time >= 0.0 && now - last_wrench_time < 0.020)
            dhdSetForceAndTorque(wrench.force[0], wrench.force[1], wrench.force[2],
                                 wrench.torque[0], wrench.torque[1], wrench.torque[2]);
        else
            dhdSetForceAndTorque(0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    }
    for (i = 0; i < 3; i++) dhdSetForceAndTorque(0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    dhdClose();
    vps_bridge_close(&bridge);
    return 0;
}

#else /* !VPS_WITH_DHD */
int main(void) {
    return vps_skeleton_without_sdk("the Force Dimension SDK", "VPS_WITH_DHD", "-ldhd");
}
#endif
