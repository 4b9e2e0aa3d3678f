/*
 * example.c: a simulated haptic device driving vps over the UDP bridge at 1 kHz.
 *
 *   gcc -std=c99 -O2 -Wall -Wextra -o example example.c -lm     (or: make)
 *   vps run --device bridge:127.0.0.1:7700 --seconds 30 &
 *   ./example 127.0.0.1:7700 10
 *
 * The device point holds the clutch for the first 0.1 s (so vps anchors it where the part
 * starts), then moves 0.15 m along -Z (towards the bay's floor) and back every 2 s. Every 100th
 * wrench received is printed; the last line is exactly `wrenches N` (N = wrenches received).
 * With VPS_DUMP=FILE set, every wrench received is written to FILE as one line
 * `FRAME FX FY FZ TX TY TZ`, each double as the 16 hex digits of its IEEE 754 bits.
 *
 * The loop sleeps to absolute deadlines (clock_nanosleep TIMER_ABSTIME), so a late wake-up does
 * not delay the following ticks: S seconds send about 1000 * S poses.
 */
#define _POSIX_C_SOURCE 200809L
#include "vps_bridge.h"

#include <inttypes.h>
#include <stdlib.h>
#include <time.h>

#define PI 3.14159265358979323846
#define AMPLITUDE 0.15 /* m */
#define PERIOD 2.0     /* s */
#define CLUTCH_UNTIL 0.1 /* s */

/* The simulated device's pose at t (s since start), device frame. */
static vps_pose simulated_pose(double t) {
    vps_pose p;
    double s = t < CLUTCH_UNTIL ? 0.0 : t - CLUTCH_UNTIL;
    double w = 2.0 * PI / PERIOD;
    memset(&p, 0, sizeof p);
    p.orientation[3] = 1.0;
    p.position[2] = -AMPLITUDE * 0.5 * (1.0 - cos(w * s));
    p.linear_velocity[2] = t < CLUTCH_UNTIL ? 0.0 : -AMPLITUDE * 0.5 * w * sin(w * s);
    return p;
}

static void add_ns(struct timespec *ts, long ns) {
    ts->tv_nsec += ns;
    while (ts->tv_nsec >= 1000000000L) {
        ts->tv_nsec -= 1000000000L;
        ts->tv_sec++;
    }
}

static void dump_wrench(FILE *f, const vps_wrench *w) {
    const double v[6] = {w->force[0], w->force[1], w->force[2],
                         w->torque[0], w->torque[1], w->torque[2]};
    int i;
    fprintf(f, "%" PRIu64, w->frame);
    for (i = 0; i < 6; i++) {
        uint64_t bits;
        memcpy(&bits, &v[i], 8);
        fprintf(f, " %016" PRIx64, bits);
    }
    fputc('\n', f);
}

/* Receives every pending wrench; prints every 100th, dumps all. Returns how many arrived. */
static uint64_t drain(vps_bridge *b, FILE *dump, uint64_t received) {
    vps_wrench w;
    uint64_t got = 0;
    while (vps_bridge_recv_wrench(b, &w) == 1) {
        got++;
        if (dump) dump_wrench(dump, &w);
        if ((received + got) % 100 == 0)
            printf("frame %" PRIu64 " force %.4f %.4f %.4f N torque %.5f %.5f %.5f N.m\n",
                   w.frame, w.force[0], w.force[1], w.force[2], w.torque[0], w.torque[1],
                   w.torque[2]);
    }
    return got;
}

int main(int argc, char **argv) {
    vps_bridge b;
    struct timespec next;
    FILE *dump = NULL;
    const char *dump_path = getenv("VPS_DUMP");
    double seconds;
    char *end;
    uint64_t ticks, k, received = 0, send_errors = 0;

    if (argc != 3) {
        fprintf(stderr, "usage: %s HOST:PORT SECONDS\n", argv[0]);
        return 2;
    }
    seconds = strtod(argv[2], &end);
    if (*end != '\0' || !(seconds > 0.0 && seconds <= 86400.0)) {
        fprintf(stderr, "SECONDS must be a number in (0, 86400], got `%s`\n", argv[2]);
        return 2;
    }
    if (vps_bridge_open(&b, argv[1], NULL) != 0) {
        fprintf(stderr, "cannot open the bridge to %s: %s\n", argv[1], strerror(errno));
        return 1;
    }
    if (dump_path && *dump_path) {
        dump = fopen(dump_path, "w");
        if (!dump) {
            fprintf(stderr, "cannot write %s: %s\n", dump_path, strerror(errno));
            return 1;
        }
    }
    ticks = (uint64_t)(seconds * 1000.0 + 0.5);
    clock_gettime(CLOCK_MONOTONIC, &next);
    for (k = 0; k < ticks; k++) {
        vps_pose p = simulated_pose((double)k * 1e-3);
        uint32_t flags = (double)k * 1e-3 < CLUTCH_UNTIL ? VPS_FLAG_CLUTCH : 0;
        /* A refused send (vps not listening yet) is counted, not fatal. */
        if (vps_bridge_send_pose(&b, &p, flags) != 0) send_errors++;
        received += drain(&b, dump, received);
        add_ns(&next, 1000000L);
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, NULL) == EINTR) {
        }
    }
    /* Collect the replies still in flight (50 ms). */
    for (k = 0; k < 50; k++) {
        received += drain(&b, dump, received);
        add_ns(&next, 1000000L);
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, NULL) == EINTR) {
        }
    }
    vps_bridge_close(&b);
    if (dump && fclose(dump) != 0) {
        fprintf(stderr, "cannot write %s: %s\n", dump_path, strerror(errno));
        return 1;
    }
    fprintf(stderr, "poses sent %" PRIu64 ", send errors %" PRIu64 "\n", ticks - send_errors,
            send_errors);
    printf("wrenches %" PRIu64 "\n", received);
    return 0;
}
