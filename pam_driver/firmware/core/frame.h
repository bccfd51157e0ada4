/* Frames of PROTOCOL.md: SYNC A5 5A, type, u16 seq, u8 length, payload (<= 64), CRC-16.
 * The decoder resynchronises like the host's (pam_driver/daq_protocol.py): on a CRC error it drops
 * only the first SYNC byte and searches again. Little-endian helpers for payloads. */
#ifndef PAM_FRAME_H
#define PAM_FRAME_H
#include <stdint.h>

#include "crc16.h"

#define FRAME_SYNC0 0xA5u
#define FRAME_SYNC1 0x5Au
#define FRAME_HEADER 6u                 /* sync 2, type 1, seq 2, length 1 */
#define FRAME_OVERHEAD 8u               /* header + CRC */
#define FRAME_MAX_PAYLOAD 64u
#define FRAME_MAX (FRAME_OVERHEAD + FRAME_MAX_PAYLOAD)

typedef struct {
    uint8_t type;
    uint16_t seq;
    uint8_t length;
    const uint8_t *payload;
} frame_t;

typedef struct {
    uint8_t buf[FRAME_MAX];
    uint8_t n;
    uint8_t pending;                    /* the size of the frame last returned (still in buf, out->
                                         * payload points into it): dropped by the next call */
    uint16_t crc;                       /* CRC-16 of buf[2 .. min(n, FRAME_HEADER + length)),
                                         * kept byte by byte by frame_decoder_push */
    uint32_t garbage;                   /* bytes before a SYNC */
    uint32_t crc_errors;                /* bad CRC or length > 64 */
} frame_decoder_t;

void frame_decoder_init(frame_decoder_t *d);
/* Feeds one byte; returns 1 and fills *out when a frame is complete (valid until the next call).
 * After a resynchronisation more frames may wait in the buffer: frame_decoder_next() returns them
 * without a new byte. */
uint8_t frame_decoder_feed(frame_decoder_t *d, uint8_t byte, frame_t *out);
uint8_t frame_decoder_next(frame_decoder_t *d, frame_t *out);
/* The CRC state of what frame_decoder_next left in the buffer (after it returned 0). */
void frame_decoder_resume(frame_decoder_t *d);

static inline uint16_t get_u16(const uint8_t *p) { return (uint16_t)(p[0] | ((uint16_t)p[1] << 8)); }

enum { FRAME_MORE = 0, FRAME_READY = 1, FRAME_RESYNC = 2 };
/* The fast path of the decoder for a buffer that starts at a frame (no frame pending): appends
 * the byte, checks SYNC and length and keeps the CRC byte by byte. FRAME_MORE: nothing to do yet;
 * FRAME_READY: a frame with a good CRC fills buf exactly (the caller handles it in place and sets
 * n = 0, crc = CRC16_INIT); FRAME_RESYNC: garbage, a bad length or CRC: frame_decoder_next (which
 * ends with frame_decoder_resume) sorts it out. */
static inline uint8_t frame_decoder_push(frame_decoder_t *d, uint8_t byte)
{
    uint8_t n = d->n;
    d->buf[n++] = byte;
    d->n = n;
    if (n <= 2)
        return byte == (n == 1 ? FRAME_SYNC0 : FRAME_SYNC1) ? FRAME_MORE : FRAME_RESYNC;
    if (n <= FRAME_HEADER) {
        d->crc = crc16_update(d->crc, byte);
        return n == FRAME_HEADER && byte > FRAME_MAX_PAYLOAD ? FRAME_RESYNC : FRAME_MORE;
    }
    uint8_t end = (uint8_t)(FRAME_HEADER + d->buf[5]);
    if (n <= end) {
        d->crc = crc16_update(d->crc, byte);
        return FRAME_MORE;
    }
    if (n < (uint8_t)(end + 2))
        return FRAME_MORE;
    return d->crc == get_u16(d->buf + end) ? FRAME_READY : FRAME_RESYNC;
}

/* Encodes a frame into out (FRAME_OVERHEAD + length bytes); returns its size. */
uint8_t frame_encode(uint8_t *out, uint8_t type, uint16_t seq, const uint8_t *payload,
                     uint8_t length);
/* The same for a payload already written at out + FRAME_HEADER (no copy). */
uint8_t frame_finish(uint8_t *out, uint8_t type, uint16_t seq, uint8_t length);
/* Only the header before such a payload; returns FRAME_HEADER + length (the CRC left to the
 * sender: the board's HAL computes it while it copies the bytes to the UART). */
uint8_t frame_header(uint8_t *out, uint8_t type, uint16_t seq, uint8_t length);

static inline void put_u16(uint8_t *p, uint16_t v) { p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); }
static inline void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); p[2] = (uint8_t)(v >> 16); p[3] = (uint8_t)(v >> 24);
}

#endif
