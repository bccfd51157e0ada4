#include <string.h>

#include "crc16.h"
#include "frame.h"

void frame_decoder_init(frame_decoder_t *d)
{
    memset(d, 0, sizeof *d);
    d->crc = CRC16_INIT;
}

void frame_decoder_resume(frame_decoder_t *d)
{
    uint8_t end = d->n;
    if (end > FRAME_HEADER && (uint8_t)(FRAME_HEADER + d->buf[5]) < end)
        end = (uint8_t)(FRAME_HEADER + d->buf[5]);
    d->crc = end > 2 ? crc16(d->buf + 2, (uint16_t)(end - 2)) : CRC16_INIT;
}

static void drop(frame_decoder_t *d, uint8_t k)
{
    memmove(d->buf, d->buf + k, (uint8_t)(d->n - k));
    d->n = (uint8_t)(d->n - k);
}

uint8_t frame_decoder_feed(frame_decoder_t *d, uint8_t byte, frame_t *out)
{
    if (d->pending) {
        drop(d, d->pending);
        d->pending = 0;
        frame_decoder_resume(d);
    }
    if (frame_decoder_push(d, byte) == FRAME_MORE)
        return 0;
    return frame_decoder_next(d, out);
}

uint8_t frame_decoder_next(frame_decoder_t *d, frame_t *out)
{
    if (d->pending) {                   /* the frame returned last: consumed now */
        drop(d, d->pending);
        d->pending = 0;
    }
    for (;;) {
        if (d->n >= 1 && d->buf[0] != FRAME_SYNC0) { d->garbage++; drop(d, 1); continue; }
        if (d->n >= 2 && d->buf[1] != FRAME_SYNC1) { d->garbage++; drop(d, 1); continue; }
        if (d->n < FRAME_HEADER)
            break;
        uint8_t length = d->buf[5];
        if (length > FRAME_MAX_PAYLOAD) { d->crc_errors++; drop(d, 1); continue; }
        uint8_t size = (uint8_t)(FRAME_OVERHEAD + length);
        if (d->n < size)
            break;
        uint16_t crc = crc16(d->buf + 2, (uint16_t)(4 + length));
        if (crc != get_u16(d->buf + FRAME_HEADER + length)) { d->crc_errors++; drop(d, 1); continue; }
        d->pending = size;              /* processed in place, dropped by the next call */
        out->type = d->buf[2];
        out->seq = get_u16(d->buf + 3);
        out->length = length;
        out->payload = d->buf + FRAME_HEADER;
        return 1;
    }
    frame_decoder_resume(d);            /* the fast path goes on from here */
    return 0;
}

uint8_t frame_encode(uint8_t *out, uint8_t type, uint16_t seq, const uint8_t *payload,
                     uint8_t length)
{
    if (length)
        memcpy(out + FRAME_HEADER, payload, length);
    return frame_finish(out, type, seq, length);
}

uint8_t frame_header(uint8_t *out, uint8_t type, uint16_t seq, uint8_t length)
{
    out[0] = FRAME_SYNC0;
    out[1] = FRAME_SYNC1;
    out[2] = type;
    put_u16(out + 3, seq);
    out[5] = length;
    return (uint8_t)(FRAME_HEADER + length);
}

uint8_t frame_finish(uint8_t *out, uint8_t type, uint16_t seq, uint8_t length)
{
    frame_header(out, type, seq, length);
    put_u16(out + FRAME_HEADER + length, crc16(out + 2, (uint16_t)(4 + length)));
    return (uint8_t)(FRAME_OVERHEAD + length);
}
