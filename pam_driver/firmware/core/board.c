#include <string.h>

#include "board.h"

/* A frame whose payload is written at frame + FRAME_HEADER already (no copy). */
static void send_frame(board_t *b, uint8_t *frame, uint8_t type, uint8_t length)
{
    b->tx(frame, frame_header(frame, type, b->seq++, length), b->ctx);
}

static void send(board_t *b, uint8_t type, const uint8_t *payload, uint8_t length)
{
    uint8_t out[FRAME_MAX];
    memcpy(out + FRAME_HEADER, payload, length);
    send_frame(b, out, type, length);
}

__attribute__((noinline)) static void send_cal(board_t *b, uint8_t result)
{
    uint8_t p[1 + CALIB_SIZE];
    p[0] = result;
    calib_to_bytes(&b->cal, p + 1);
    send(b, T_CAL, p, sizeof p);
}

uint8_t board_status(const board_t *b)
{
    uint8_t s = 0;
    if (b->faults || b->comm_lost)
        s |= ST_VENTED;
    if (b->faults)
        s |= ST_FAULT;
    if (b->zero_left)
        s |= ST_ZEROING;
    return s;
}

static void update_output(board_t *b)
{
    const uint16_t *target = board_safe(b) ? b->cal.safe_code : b->cmd;
    if (target[0] != b->dac[0] || target[1] != b->dac[1]) {
        b->dac[0] = target[0];
        b->dac[1] = target[1];
        b->dac_dirty = 1;
    }
}

void board_init(board_t *b, const calib_t *stored, uint8_t reset_cause, board_tx_t tx,
                board_store_t store, void *ctx)
{
    memset(b, 0, sizeof *b);
    if (stored && calib_valid(stored)) {
        b->cal = *stored;
    } else {
        calib_defaults(&b->cal);
        b->cal_defaulted = 1;
    }
    frame_decoder_init(&b->rx);
    b->tx = tx;
    b->store = store;
    b->ctx = ctx;
    b->reset_cause = reset_cause;
    if (reset_cause & RESET_WATCHDOG)
        b->faults |= FAULT_WATCHDOG_RESET;
    b->dac[0] = b->cal.safe_code[0];
    b->dac[1] = b->cal.safe_code[1];
    b->dac_dirty = 1;                   /* the HAL writes the safe output at once */
}

__attribute__((noinline)) static void on_hello(board_t *b, const frame_t *f)
{
    uint8_t p[7] = {PROTO_MAJOR, PROTO_MINOR, 0, 0, 12, 12, b->cal.fitted};
    put_u16(p + 2, SAMPLE_RATE_HZ);
    send(b, T_HELLO_ACK, p, sizeof p);
    if (f->payload[0] == PROTO_MAJOR) {
        b->streaming = 1;
        b->commanded = 0;               /* safe output until this session's first COMMAND */
    } else {
        b->streaming = 0;
    }
}

static inline void on_command(board_t *b, const uint8_t *payload)
{
    uint8_t clipped = 0;
    b->cmd[0] = calib_command(&b->cal, 0, get_u16(payload), &clipped);
    b->cmd[1] = calib_command(&b->cal, 1, get_u16(payload + 2), &clipped);
    if (clipped)
        b->clipped++;
    b->comm_lost = 0;
    b->commanded = 1;
}

__attribute__((noinline)) static void on_arm(board_t *b)
{
    uint8_t keep = 0;
    if ((b->faults & FAULT_ESTOP) && b->estop_now)
        keep |= FAULT_ESTOP;
    if ((b->faults & FAULT_OVERPRESSURE) && b->over_count)
        keep |= FAULT_OVERPRESSURE;
    b->faults = keep;
    b->commanded = 0;                   /* the safe output until the next COMMAND */
}

__attribute__((noinline)) static void on_zero(board_t *b)
{
    if (!board_safe(b)) {               /* only while the board holds the safe output */
        send_cal(b, CAL_NOT_SAFE);
        return;
    }
    b->zero_left = ZERO_SAMPLES;
    memset(b->zero_sum, 0, sizeof b->zero_sum);
    send_cal(b, CAL_STARTED);
}

__attribute__((noinline)) static void on_cal_write(board_t *b, const frame_t *f)
{
    if (!board_safe(b) || b->zero_left) {
        send_cal(b, CAL_NOT_SAFE);
        return;
    }
    calib_t c;
    uint8_t bytes[CALIB_SIZE];
    memcpy(bytes, f->payload, CALIB_SIZE - 2);
    bytes[CALIB_SIZE - 2] = bytes[CALIB_SIZE - 1] = 0;
    calib_from_bytes(&c, bytes);
    calib_seal(&c);
    if (!calib_valid(&c)) {
        send_cal(b, CAL_INVALID);
        return;
    }
    b->cal = c;
    b->cal_defaulted = 0;
    if (b->store)
        b->store(&b->cal, b->ctx);
    send_cal(b, CAL_OK);
}

__attribute__((noinline)) static void on_frame(board_t *b, const frame_t *fp)
{
    frame_t f = *fp;
    static const uint8_t need[8] = {0xFF, 2, 4, 0, 0, 0, CALIB_SIZE - 2, 0};
    if (f.type >= sizeof need || need[f.type] == 0xFF || f.length < need[f.type]) {
        b->protocol_errors++;
        return;
    }
    b->host_frames++;
    b->ms_since_host = 0;
    switch (f.type) {
    case T_HELLO: on_hello(b, &f); break;
    case T_COMMAND: on_command(b, f.payload); break;
    case T_ARM: on_arm(b); break;
    case T_ZERO: on_zero(b); break;
    case T_CAL_WRITE: on_cal_write(b, &f); break;
    case T_CAL_READ: send_cal(b, CAL_OK); break;
    default: break;                     /* HEARTBEAT */
    }
    update_output(b);
}

void board_rx_frame_end(board_t *b, uint8_t pushed)
{
    frame_decoder_t *d = &b->rx;
    frame_t f;
    uint8_t type = d->buf[2];
    if (pushed == FRAME_READY && (type == T_HEARTBEAT || (type == T_COMMAND && d->buf[5] >= 4))) {
        b->host_frames++;               /* the 1 kHz and 20 Hz frames, as on_frame does them */
        b->ms_since_host = 0;
        if (type == T_COMMAND) {
            on_command(b, d->buf + FRAME_HEADER);
            update_output(b);
        }
        d->n = 0;
        d->crc = CRC16_INIT;
        return;
    }
    if (pushed == FRAME_READY) {        /* one whole frame in the buffer */
        f.type = type;
        f.length = d->buf[5];
        f.payload = d->buf + FRAME_HEADER;
        on_frame(b, &f);
        d->n = 0;
        d->crc = CRC16_INIT;
        return;
    }
    while (frame_decoder_next(d, &f))   /* garbage, a CRC error: resynchronise */
        on_frame(b, &f);
}

static void zero_step(board_t *b, const board_inputs_t *in)
{
    for (uint8_t i = 0; i < 2; i++)     /* P1, P2: the muscles are at atmosphere when vented */
        b->zero_sum[i] += in->adc[i];
    if (--b->zero_left)
        return;
    int16_t off[2];
    for (uint8_t i = 0; i < 2; i++) {
        int32_t avg = (b->zero_sum[i] + ZERO_SAMPLES / 2) / ZERO_SAMPLES;
        int32_t o = avg - b->cal.nominal_zero;
        if (o > CALIB_ZERO_RANGE || o < -CALIB_ZERO_RANGE) {
            send_cal(b, CAL_NOT_VENTED);
            return;
        }
        off[i] = (int16_t)o;
    }
    b->cal.zero_offset[0] = off[0];
    b->cal.zero_offset[1] = off[1];
    calib_seal(&b->cal);
    if (b->store)
        b->store(&b->cal, b->ctx);
    send_cal(b, CAL_OK);
}

static void send_sample(board_t *b, const uint16_t p[3], const board_inputs_t *in, uint8_t status)
{
    uint8_t out[FRAME_OVERHEAD + 17];
    uint8_t *s = out + FRAME_HEADER;
    put_u32(s, b->tick);
    put_u16(s + 4, p[0]);
    put_u16(s + 6, p[1]);
    put_u32(s + 8, (uint32_t)in->encoder);
    put_u16(s + 12, in->adc[2]);
    s[14] = status;
    put_u16(s + 15, p[2]);
    send_frame(b, out, T_SAMPLE, (b->cal.fitted & FITTED_SUPPLY) ? 17 : 15);
}

void board_send_heartbeat(board_t *b)
{
    if (!b->heartbeat_due)
        return;
    b->heartbeat_due = 0;
    if (!b->streaming)
        return;
    uint8_t status = board_status(b) | (b->estop_now ? ST_ESTOP : 0);
    uint8_t out[FRAME_OVERHEAD + 32];
    uint8_t *h = out + FRAME_HEADER;
    put_u32(h, b->host_frames);
    put_u32(h + 4, b->rx.crc_errors);
    put_u32(h + 8, b->watchdog_trips);
    h[12] = status;
    /* 1.2 */
    h[13] = b->faults;
    h[14] = b->reset_cause;
    h[15] = b->cal_defaulted;
    put_u16(h + 16, b->overruns);
    put_u16(h + 18, b->worst_tick_us);
    put_u16(h + 20, b->uart_errors);
    put_u16(h + 22, b->protocol_errors);
    put_u32(h + 24, b->clipped);
    put_u16(h + 28, b->dac[0]);
    put_u16(h + 30, b->dac[1]);
    send_frame(b, out, T_DEVICE_HEARTBEAT, 32);
}

void board_tick(board_t *b, const board_inputs_t *in)
{
    b->tick++;
    b->estop_now = in->estop;
    if (in->estop)
        b->faults |= FAULT_ESTOP;
    uint16_t p[3];
    for (uint8_t i = 0; i < 3; i++) {
        uint8_t adc = i < 2 ? i : 3;
        p[i] = calib_pressure(&b->cal, i, in->adc[adc]);
    }
    if (p[0] > b->cal.p_max_counts || p[1] > b->cal.p_max_counts) {
        if (b->over_count < 0xFF)
            b->over_count++;
        if (b->over_count >= b->cal.p_max_samples)
            b->faults |= FAULT_OVERPRESSURE;
    } else {
        b->over_count = 0;
    }
    if (b->streaming) {
        b->ms_since_host++;
        if (b->ms_since_host > COMM_LOSS_MS && !b->comm_lost) {
            b->comm_lost = 1;
            b->watchdog_trips++;
        }
        if (b->ms_since_host > STREAM_STOP_MS)
            b->streaming = 0;
    }
    if (b->zero_left)
        zero_step(b, in);
    update_output(b);
    uint8_t status = board_status(b) | (in->estop ? ST_ESTOP : 0);
    if (b->streaming) {
        send_sample(b, p, in, status);
        if (++b->heartbeat_in >= HEARTBEAT_EVERY) {
            b->heartbeat_in = 0;
            b->heartbeat_due = 1;       /* board_send_heartbeat: the HAL's moment */
        }
    }
}
