/*
 * vps_skeleton.h: what the device skeletons (openhaptics_skeleton.c, dhd_skeleton.c) share: the
 * command line and opening the bridge, and the stub built without the vendor SDK. Not part of the
 * client API (that is vps_bridge.h, which this includes); a skeleton only includes this header,
 * from the same directory, so `gcc -std=c99 dhd_skeleton.c` still needs no other file or flag.
 * Every function is `static inline`, as in vps_bridge.h.
 */
#ifndef VPS_SKELETON_H
#define VPS_SKELETON_H

#include "vps_bridge.h"

/* Opens `bridge` to the one argument HOST:PORT. Returns 0 when open; otherwise says why on stderr
 * and returns the exit status for main: 2 for a wrong command line, 1 when the bridge cannot be
 * opened. */
static inline int vps_skeleton_open(vps_bridge *bridge, int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: %s HOST:PORT\n", argv[0]);
        return 2;
    }
    if (vps_bridge_open(bridge, argv[1], NULL) != 0) {
        perror("vps_bridge_open");
        return 1;
    }
    return 0;
}

/* The stub's whole work when a skeleton is built without its SDK: says which SDK (`sdk`), which
 * define (`define`) and which libraries (`libs`) the real build needs, and returns exit status 1. */
static inline int vps_skeleton_without_sdk(const char *sdk, const char *define, const char *libs) {
    fprintf(stderr, "built without %s: define %s and link %s\n", sdk, define, libs);
    return 1;
}

#endif /* VPS_SKELETON_H */
