/* Frames of PROTOCOL.md: SYNC A5 5A, type, u16 seq, u8 length, payload (<= 64), CRC-16.
 * The decoder resynchronises like the host's (pam_driver/daq_protocol.py): on a CRC error it drops
 * only the first SYNC byte and searches again. Little-endian helpers for payloads. */
#ifndef PAM_FRAME_H
#define PAM_FRAME_H
#include <stdint.h>

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
    uint8_t frame[FRAME_MAX];           /* the last complete frame (out->payload points here) */
    uint32_t garbage;                   /* bytes before a SYNC */
    uint32_t crc_errors;                /* bad CRC or length > 64 */
} frame_decoder_t;

void frame_decoder_init(frame_decoder_t *d);
/* Feeds one byte; returns 1 and fills *out when a frame is complete (valid until the next call).
 * After a resynchronisation more frames may wait in the buffer: frame_decoder_next() returns them
 * without a new byte. */
uint8_t frame_decoder_feed(frame_decoder_t *d, uint8_t byte, frame_t *out);
uint8_t frame_decoder_next(frame_decoder_t *d, frame_t *out);

/* Encodes a frame into out (FRAME_OVERHEAD + length bytes); returns its size. */
uint8_t frame_encode(uint8_t *out, uint8_t type, uint16_t seq, const uint8_t *payload,
                     uint8_t length);

static inline void put_u16(uint8_t *p, uint16_t v) { p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); }
static inline void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); p[2] = (uint8_t)(v >> 16); p[3] = (uint8_t)(v >> 24);
}
static inline uint16_t get_u16(const uint8_t *p) { return (uint16_t)(p[0] | ((uint16_t)p[1] << 8)); }

#endif
