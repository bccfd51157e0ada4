#include <string.h>

#include "crc16.h"
#include "frame.h"

void frame_decoder_init(frame_decoder_t *d)
{
    memset(d, 0, sizeof *d);
}

static void drop(frame_decoder_t *d, uint8_t k)
{
    memmove(d->buf, d->buf + k, (uint8_t)(d->n - k));
    d->n = (uint8_t)(d->n - k);
}

uint8_t frame_decoder_feed(frame_decoder_t *d, uint8_t byte, frame_t *out)
{
    if (d->n >= FRAME_MAX)              /* cannot happen: a frame is complete at FRAME_MAX */
        drop(d, 1);
    d->buf[d->n++] = byte;
    /* fast path: SYNC already checked (n > 2), header incomplete or payload still to come */
    if (d->n > 2 && (d->n < FRAME_HEADER ||
                     (d->buf[5] <= FRAME_MAX_PAYLOAD && d->n < FRAME_OVERHEAD + d->buf[5])))
        return 0;
    return frame_decoder_next(d, out);
}

uint8_t frame_decoder_next(frame_decoder_t *d, frame_t *out)
{
    for (;;) {
        if (d->n >= 1 && d->buf[0] != FRAME_SYNC0) { d->garbage++; drop(d, 1); continue; }
        if (d->n >= 2 && d->buf[1] != FRAME_SYNC1) { d->garbage++; drop(d, 1); continue; }
        if (d->n < FRAME_HEADER)
            return 0;
        uint8_t length = d->buf[5];
        if (length > FRAME_MAX_PAYLOAD) { d->crc_errors++; drop(d, 1); continue; }
        uint8_t size = (uint8_t)(FRAME_OVERHEAD + length);
        if (d->n < size)
            return 0;
        uint16_t crc = crc16(d->buf + 2, (uint16_t)(4 + length));
        if (crc != get_u16(d->buf + FRAME_HEADER + length)) { d->crc_errors++; drop(d, 1); continue; }
        memcpy(d->frame, d->buf, size);
        drop(d, size);
        out->type = d->frame[2];
        out->seq = get_u16(d->frame + 3);
        out->length = length;
        out->payload = d->frame + FRAME_HEADER;
        return 1;
    }
}

uint8_t frame_encode(uint8_t *out, uint8_t type, uint16_t seq, const uint8_t *payload,
                     uint8_t length)
{
    out[0] = FRAME_SYNC0;
    out[1] = FRAME_SYNC1;
    out[2] = type;
    put_u16(out + 3, seq);
    out[5] = length;
    if (length)
        memcpy(out + FRAME_HEADER, payload, length);
    put_u16(out + FRAME_HEADER + length, crc16(out + 2, (uint16_t)(4 + length)));
    return (uint8_t)(FRAME_OVERHEAD + length);
}
