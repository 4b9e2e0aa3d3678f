/*
 * openhaptics_skeleton.c: where the vps bridge calls go in an OpenHaptics (HDAPI) servo callback,
 * for a 3D Systems Touch / Touch X / Phantom. A commented skeleton, not tested here: it compiles
 * against the real SDK only when VPS_WITH_OPENHAPTICS is defined, e.g.
 *
 *   gcc -std=c99 -O2 -DVPS_WITH_OPENHAPTICS -o touch_bridge openhaptics_skeleton.c -lHD -lHDU -lm
 *   vps run --device bridge:127.0.0.1:7700 --map-scale 5 --seconds 600 &
 *   ./touch_bridge 127.0.0.1:7700
 *
 * Without that define it builds, one file at a time (each has its own main; example.c too), a
 * stub that says so: `gcc -std=c99 -O2 -o STUB FILE.c -lm` never needs the SDK.
 *
 * Units: HDAPI positions are in mm and velocities in mm/s; vps wants m and m/s. Forces are N both
 * sides. HD_CURRENT_TORQUE (6-DOF output Phantoms only) is in mN.m; vps sends N.m. The Touch
 * renders force only (3-DOF output): drop the torque there.
 */
#define _POSIX_C_SOURCE 200809L
#include "vps_skeleton.h"

#ifdef VPS_WITH_OPENHAPTICS
#include <HD/hd.h>
#include <time.h>

/* Written by the servo thread only. */
static vps_bridge bridge;
static vps_wrench last_wrench;
static unsigned long servo_ticks = 0;      /* servo callbacks so far (1 kHz by default) */
static unsigned long last_wrench_tick = 0; /* 0: no wrench yet */

/* The 1 kHz servo callback: read the device, send the pose, apply the newest wrench. */
HDCallbackCode HDCALLBACK vps_servo(void *unused) {
    HDdouble transform[16], velocity[3], angular[3], force[3] = {0, 0, 0};
    HDint buttons = 0;
    double rotation[9];
    vps_pose pose;
    int i;
    (void)unused;
    hdBeginFrame(hdGetCurrentDevice());
    servo_ticks++;

    /* 1. Read: HD_CURRENT_TRANSFORM is column-major 4x4, translation in mm. */
    hdGetDoublev(HD_CURRENT_TRANSFORM, transform);
    hdGetDoublev(HD_CURRENT_VELOCITY, velocity);          /* mm/s */
    hdGetDoublev(HD_CURRENT_ANGULAR_VELOCITY, angular);   /* rad/s */
    hdGetIntegerv(HD_CURRENT_BUTTONS, &buttons);
    for (i = 0; i < 3; i++) {
        pose.position[i] = transform[12 + i] * 1e-3;
        pose.linear_velocity[i] = velocity[i] * 1e-3;
        pose.angular_velocity[i] = angular[i];
    }
    for (i = 0; i < 9; i++) rotation[i] = transform[(i % 3) * 4 + i / 3]; /* to row-major */
    if (vps_quat_from_matrix(rotation, pose.orientation) != 0) {
        pose.orientation[0] = pose.orientation[1] = pose.orientation[2] = 0.0;
        pose.orientation[3] = 1.0;
    }

    /* 2. Send: the second stylus button is the clutch (hold it to re-centre the handle). */
    vps_bridge_send_pose(&bridge, &pose, (buttons & HD_DEVICE_BUTTON_2) ? VPS_FLAG_CLUTCH : 0);

    /* 3. Receive the newest wrench without blocking; keep the previous one otherwise. */
    if (vps_bridge_recv_latest(&bridge, &last_wrench) > 0) last_wrench_tick = servo_ticks;

    /* 4. Apply it, or zero when vps has been silent for 20 ticks (20 ms at the default 1 kHz
     *    scheduler rate: vps gone, network broken). */
    if (last_wrench_tick != 0 && servo_ticks - last_wrench_tick < 20)
        for (i = 0; i < 3; i++) force[i] = last_wrench.force[i];
    hdSetDoublev(HD_CURRENT_FORCE, force);
    /* 6-DOF output Phantoms: HDdouble torque[3] = {1e3 * last_wrench.torque[0], ...} (mN.m);
     * hdSetDoublev(HD_CURRENT_TORQUE, torque); */

    hdEndFrame(hdGetCurrentDevice());
    return HD_CALLBACK_CONTINUE;
}

int main(int argc, char **argv) {
    HHD device;
    HDErrorInfo error;
    HDSchedulerHandle servo;
    int status;
    if ((status = vps_skeleton_open(&bridge, argc, argv)) != 0) return status;
    device = hdInitDevice(HD_DEFAULT_DEVICE);
    if (HD_DEVICE_ERROR(error = hdGetError())) {
        fprintf(stderr, "hdInitDevice failed\n");
        return 1;
    }
    hdEnable(HD_FORCE_OUTPUT);
    servo = hdScheduleAsynchronous(vps_servo, NULL, HD_MAX_SCHEDULER_PRIORITY);
    hdStartScheduler();
    fprintf(stderr, "running; press Enter to stop\n");
    (void)getchar();
    /* Stopping the scheduler ends force output (the device renders zero). */
    hdStopScheduler();
    hdUnschedule(servo);
    hdDisableDevice(device);
    vps_bridge_close(&bridge);
    return 0;
}

#else /* !VPS_WITH_OPENHAPTICS */
int main(void) {
    return vps_skeleton_without_sdk("OpenHaptics", "VPS_WITH_OPENHAPTICS", "-lHD -lHDU");
}
#endif
