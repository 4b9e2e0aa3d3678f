/*
 * vps_bridge.h: a single-header C99 client for the vps UDP device bridge.
 *
 * Dependencies: the C library and BSD sockets (POSIX). No allocation. Include it in any number of
 * translation units: every function is `static inline`. Define _POSIX_C_SOURCE (200112L or later)
 * before your first system include, or compile with -D_POSIX_C_SOURCE=200809L, so that
 * getaddrinfo is declared in strict C99 mode. Link with -lm (sqrt).
 *
 * Protocol (version 1, the one documented in crates/vps-input/src/bridge/protocol.rs):
 * every integer and every double is LITTLE-ENDIAN (doubles as IEEE 754 binary64 bit patterns),
 * whatever the host's byte order; this header converts explicitly.
 *
 *   offset size field
 *        0    4 magic "VPSB"
 *        4    1 version = 1
 *        5    1 kind: 1 PoseIn, 3 PoseInFlags (client -> vps), 2 WrenchOut (vps -> client)
 *        6   16 token (shared secret; all zero when vps has none)
 *       22    8 sequence u64 (strictly increasing per sender)
 *       30      payload
 *   PoseInFlags (138 bytes): position xyz (m), orientation quaternion xyzw (unit), linear velocity
 *                xyz (m/s), angular velocity xyz (rad/s): 13 doubles, then flags u32
 *                (bit 0 VPS_FLAG_CLUTCH; other bits must be zero)
 *   WrenchOut   (86 bytes): force xyz (N), torque xyz (N.m): 6 doubles, then frame u64
 *
 * Poses are in the device's own frame; vps maps them into the scene and maps the wrench back
 * (see docs/devices.md). Typical use, in a 1 kHz servo callback:
 *
 *   vps_bridge b;
 *   if (vps_bridge_open(&b, "127.0.0.1:7700", NULL) != 0) { perror("vps_bridge_open"); ... }
 *   ... every ms:
 *   vps_bridge_send_pose(&b, &pose, clutch ? VPS_FLAG_CLUTCH : 0);
 *   if (vps_bridge_recv_latest(&b, &wrench) > 0) apply(wrench.force, wrench.torque);
 *   ... at the end (and before, command zero force on the device):
 *   vps_bridge_close(&b);
 *
 * Safety: if no wrench arrives for a while (vps gone), command zero force on your device.
 */
#ifndef VPS_BRIDGE_H
#define VPS_BRIDGE_H

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <netdb.h>
#include <netinet/in.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <unistd.h>

#define VPS_BRIDGE_VERSION 1
#define VPS_KIND_POSE_IN 1
#define VPS_KIND_WRENCH_OUT 2
#define VPS_KIND_POSE_IN_FLAGS 3
#define VPS_FLAG_CLUTCH 1u
#define VPS_HEADER_LEN 30
#define VPS_POSE_IN_FLAGS_LEN 138
#define VPS_WRENCH_OUT_LEN 86

/* One handle sample in the device frame, SI units. */
typedef struct {
    double position[3];         /* m */
    double orientation[4];      /* unit quaternion x, y, z, w */
    double linear_velocity[3];  /* m/s */
    double angular_velocity[3]; /* rad/s */
} vps_pose;

/* One wrench received from vps, device frame, already scaled and within the device's limits. */
typedef struct {
    double force[3];  /* N */
    double torque[3]; /* N.m */
    uint64_t frame;   /* vps's write counter (1 for its first write) */
} vps_wrench;

/* A connected bridge client. */
typedef struct {
    int fd;
    uint8_t token[16];
    uint64_t sequence;
} vps_bridge;

static inline void vps_put_u64(uint8_t *p, uint64_t v) {
    int i;
    for (i = 0; i < 8; i++) p[i] = (uint8_t)(v >> (8 * i));
}

static inline uint64_t vps_get_u64(const uint8_t *p) {
    uint64_t v = 0;
    int i;
    for (i = 0; i < 8; i++) v |= (uint64_t)p[i] << (8 * i);
    return v;
}

static inline void vps_put_f64(uint8_t *p, double d) {
    uint64_t bits;
    memcpy(&bits, &d, 8); /* the IEEE 754 bit pattern, in host order */
    vps_put_u64(p, bits);
}

static inline double vps_get_f64(const uint8_t *p) {
    uint64_t bits = vps_get_u64(p);
    double d;
    memcpy(&d, &bits, 8);
    return d;
}

/* Encodes a PoseInFlags datagram into out (VPS_POSE_IN_FLAGS_LEN bytes); returns its length. */
static inline size_t vps_encode_pose(uint8_t out[VPS_POSE_IN_FLAGS_LEN], const uint8_t token[16],
                                     uint64_t sequence, const vps_pose *p, uint32_t flags) {
    const double *groups[4];
    const int sizes[4] = {3, 4, 3, 3};
    size_t at = VPS_HEADER_LEN;
    int g, i;
    groups[0] = p->position;
    groups[1] = p->orientation;
    groups[2] = p->linear_velocity;
    groups[3] = p->angular_velocity;
    memcpy(out, "VPSB", 4);
    out[4] = VPS_BRIDGE_VERSION;
    out[5] = VPS_KIND_POSE_IN_FLAGS;
    memcpy(out + 6, token, 16);
    vps_put_u64(out + 22, sequence);
    for (g = 0; g < 4; g++)
        for (i = 0; i < sizes[g]; i++, at += 8) vps_put_f64(out + at, groups[g][i]);
    for (i = 0; i < 4; i++) out[at + i] = (uint8_t)(flags >> (8 * i));
    return VPS_POSE_IN_FLAGS_LEN;
}

/* Decodes a WrenchOut datagram; 1 when valid (right length, magic, version, kind, token, finite
 * values), else 0. */
static inline int vps_decode_wrench(const uint8_t *buf, size_t len, const uint8_t token[16],
                                    vps_wrench *w) {
    int i;
    if (len != VPS_WRENCH_OUT_LEN || memcmp(buf, "VPSB", 4) != 0 ||
        buf[4] != VPS_BRIDGE_VERSION || buf[5] != VPS_KIND_WRENCH_OUT ||
        memcmp(buf + 6, token, 16) != 0)
        return 0;
    for (i = 0; i < 3; i++) {
        w->force[i] = vps_get_f64(buf + VPS_HEADER_LEN + 8 * i);
        w->torque[i] = vps_get_f64(buf + VPS_HEADER_LEN + 24 + 8 * i);
        if (!isfinite(w->force[i]) || !isfinite(w->torque[i])) return 0;
    }
    w->frame = vps_get_u64(buf + VPS_HEADER_LEN + 48);
    return 1;
}

/* Opens a non-blocking UDP socket connected to "HOST:PORT" (IPv4 name or address; use
 * "[v6addr]:PORT" for IPv6). token: the 16-byte secret vps was given, or NULL for none.
 * Returns 0, or -1 with errno set (EINVAL for a malformed address). Blocks only for the name
 * lookup. */
static inline int vps_bridge_open(vps_bridge *b, const char *host_port, const uint8_t *token) {
    char host[256];
    const char *colon = strrchr(host_port, ':');
    const char *start = host_port;
    size_t n;
    struct addrinfo hints, *res = NULL, *ai;
    int fd = -1, rc;
    if (colon == NULL || colon[1] == '\0') { errno = EINVAL; return -1; }
    n = (size_t)(colon - host_port);
    if (n >= 2 && host_port[0] == '[' && host_port[n - 1] == ']') { start++; n -= 2; }
    if (n == 0 || n >= sizeof host) { errno = EINVAL; return -1; }
    memcpy(host, start, n);
    host[n] = '\0';
    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_DGRAM;
    rc = getaddrinfo(host, colon + 1, &hints, &res);
    if (rc != 0) { errno = EINVAL; return -1; }
    for (ai = res; ai != NULL; ai = ai->ai_next) {
        fd = socket(ai->ai_family, ai->ai_socktype, ai->ai_protocol);
        if (fd < 0) continue;
        if (connect(fd, ai->ai_addr, ai->ai_addrlen) == 0 &&
            fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK) == 0)
            break;
        close(fd);
        fd = -1;
    }
    freeaddrinfo(res);
    if (fd < 0) return -1;
    b->fd = fd;
    if (token != NULL) memcpy(b->token, token, 16); else memset(b->token, 0, 16);
    b->sequence = 0;
    return 0;
}

/* Sends the next pose (sequence numbers start at 1). flags: 0, or VPS_FLAG_CLUTCH while the
 * clutch is held. Returns 0, or -1 with errno set (EAGAIN: socket buffer full, pose dropped).
 * Never blocks. */
static inline int vps_bridge_send_pose(vps_bridge *b, const vps_pose *p, uint32_t flags) {
    uint8_t out[VPS_POSE_IN_FLAGS_LEN];
    size_t len = vps_encode_pose(out, b->token, ++b->sequence, p, flags);
    ssize_t sent = send(b->fd, out, len, 0);
    return sent == (ssize_t)len ? 0 : -1;
}

/* Receives the next pending wrench without blocking: 1 and *w filled, 0 when none is pending,
 * -1 with errno set on a socket error (ECONNREFUSED: nothing listens at the address). Invalid
 * datagrams are skipped. */
static inline int vps_bridge_recv_wrench(vps_bridge *b, vps_wrench *w) {
    uint8_t buf[VPS_WRENCH_OUT_LEN + 1];
    for (;;) {
        ssize_t n = recv(b->fd, buf, sizeof buf, 0);
        if (n < 0) {
            if (errno == EAGAIN || errno == EWOULDBLOCK) return 0;
            if (errno == EINTR) continue;
            return -1;
        }
        if (vps_decode_wrench(buf, (size_t)n, b->token, w)) return 1;
    }
}

/* Drains every pending wrench without blocking and keeps the newest in *w. Returns how many
 * valid wrenches were drained (0: none pending, *w untouched), or -1 on a socket error. */
static inline int vps_bridge_recv_latest(vps_bridge *b, vps_wrench *w) {
    int count = 0, rc;
    vps_wrench next;
    while ((rc = vps_bridge_recv_wrench(b, &next)) == 1) {
        *w = next;
        count++;
    }
    return rc < 0 ? -1 : count;
}

/* The unit quaternion (x, y, z, w) of a rotation matrix given row-major (m[3 * row + col]), e.g.
 * a device's orientation frame. Returns 0, or -1 when the result is not finite. */
static inline int vps_quat_from_matrix(const double m[9], double q[4]) {
    double t = m[0] + m[4] + m[8], s, n;
    if (t > 0.0) {
        s = sqrt(t + 1.0) * 2.0;
        q[3] = 0.25 * s;
        q[0] = (m[7] - m[5]) / s;
        q[1] = (m[2] - m[6]) / s;
        q[2] = (m[3] - m[1]) / s;
    } else if (m[0] > m[4] && m[0] > m[8]) {
        s = sqrt(1.0 + m[0] - m[4] - m[8]) * 2.0;
        q[3] = (m[7] - m[5]) / s;
        q[0] = 0.25 * s;
        q[1] = (m[1] + m[3]) / s;
        q[2] = (m[2] + m[6]) / s;
    } else if (m[4] > m[8]) {
        s = sqrt(1.0 + m[4] - m[0] - m[8]) * 2.0;
        q[3] = (m[2] - m[6]) / s;
        q[0] = (m[1] + m[3]) / s;
        q[1] = 0.25 * s;
        q[2] = (m[5] + m[7]) / s;
    } else {
        s = sqrt(1.0 + m[8] - m[0] - m[4]) * 2.0;
        q[3] = (m[3] - m[1]) / s;
        q[0] = (m[2] + m[6]) / s;
        q[1] = (m[5] + m[7]) / s;
        q[2] = 0.25 * s;
    }
    n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (!isfinite(n) || n == 0.0) return -1;
    q[0] /= n; q[1] /= n; q[2] /= n; q[3] /= n;
    return 0;
}

/* Closes the socket. */
static inline void vps_bridge_close(vps_bridge *b) {
    if (b->fd >= 0) close(b->fd);
    b->fd = -1;
}

#endif /* VPS_BRIDGE_H */
