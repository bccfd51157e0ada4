/* Host unit tests of the portable core (gcc on the build machine): crc, framing, the session, the
 * board's safety and its calibration. Exit status 0 when every check passes. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../core/board.h"
#include "../core/crc16.h"
#include "../core/frame.h"

static int failures, checks;
#define CHECK(cond) do { checks++; if (!(cond)) { failures++; \
    fprintf(stderr, "%s:%d: CHECK(%s) failed\n", __FILE__, __LINE__, #cond); } } while (0)

/* what the board sent, decoded */
typedef struct { uint8_t type; uint8_t length; uint8_t payload[64]; } sent_t;
static sent_t sent[4096];
static int n_sent;
static frame_decoder_t host_rx;
static calib_t stored;
static int stores;

static void tx(const uint8_t *frame, uint8_t n, void *ctx)
{
    (void)ctx;
    frame_t f;
    uint8_t bytes[FRAME_MAX];           /* the HAL's part: the CRC after header and payload */
    memcpy(bytes, frame, n);
    put_u16(bytes + n, crc16(frame + 2, (uint16_t)(n - 2)));
    n = (uint8_t)(n + 2);
    for (uint8_t i = 0; i < n; i++)
        if (frame_decoder_feed(&host_rx, bytes[i], &f)) {
            if (n_sent == 4096)
                n_sent = 0;
            sent[n_sent].type = f.type;
            sent[n_sent].length = f.length;
            memcpy(sent[n_sent].payload, f.payload, f.length);
            n_sent++;
        }
}

static void store(const calib_t *c, void *ctx) { (void)ctx; stored = *c; stores++; }

static void host(board_t *b, uint8_t type, const uint8_t *payload, uint8_t length)
{
    static uint16_t seq;
    uint8_t out[FRAME_MAX];
    uint8_t n = frame_encode(out, type, seq++, payload, length);
    for (uint8_t i = 0; i < n; i++)
        board_rx_byte(b, out[i]);
}

static void hello(board_t *b, uint8_t major) { uint8_t p[2] = {major, 1}; host(b, T_HELLO, p, 2); }
static void command(board_t *b, uint16_t u1, uint16_t u2)
{
    uint8_t p[4];
    put_u16(p, u1);
    put_u16(p + 2, u2);
    host(b, T_COMMAND, p, 4);
}

static board_inputs_t inputs(uint16_t p1, uint16_t p2)
{
    board_inputs_t in = {{p1, p2, 2048, 1200}, -42, 0};
    return in;
}

static void ticks(board_t *b, int n, const board_inputs_t *in)
{
    while (n--) {
        board_tick(b, in);
        board_send_heartbeat(b);
    }
}
static int count(uint8_t type) { int k = 0; for (int i = 0; i < n_sent; i++) k += sent[i].type == type; return k; }
static const sent_t *last(uint8_t type)
{
    for (int i = n_sent - 1; i >= 0; i--)
        if (sent[i].type == type)
            return &sent[i];
    return NULL;
}

static void fresh(board_t *b, uint8_t reset)
{
    n_sent = 0;
    frame_decoder_init(&host_rx);
    calib_t c;
    calib_defaults(&c);
    c.safe_code[0] = 2048;              /* a 5/3 valve's closed centre is not 0 V */
    c.safe_code[1] = 2047;
    c.cmd_max[1] = 3000;
    calib_seal(&c);
    board_init(b, &c, reset, tx, store, NULL);
}

static void test_crc_and_frames(void)
{
    CHECK(crc16((const uint8_t *)"123456789", 9) == 0x29B1);
    uint8_t buf[3 * FRAME_MAX], payload[4] = {1, 2, 3, 4};
    uint8_t n = frame_encode(buf, T_COMMAND, 0x1234, payload, 4);
    CHECK(n == 12 && buf[0] == 0xA5 && buf[1] == 0x5A && buf[3] == 0x34 && buf[4] == 0x12);
    /* garbage, a false SYNC, a corrupted frame, then a true frame: only the true one decodes */
    uint8_t stream[128];
    int k = 0;
    stream[k++] = 0x00; stream[k++] = 0xA5; stream[k++] = 0x5A;
    memcpy(stream + k, buf, n); stream[k + 7] ^= 0xFF; k += n;
    for (int i = 0; i < 8; i++, k += n)         /* the false SYNC's length (0x34) spans 4 */
        memcpy(stream + k, buf, n);
    frame_decoder_t d;
    frame_decoder_init(&d);
    frame_t f;
    int frames = 0;
    for (int i = 0; i < k; i++)
        for (uint8_t got = frame_decoder_feed(&d, stream[i], &f); got; got = frame_decoder_next(&d, &f)) {
            frames++;
            CHECK(f.type == T_COMMAND && f.seq == 0x1234 && f.length == 4 && f.payload[3] == 4);
        }
    CHECK(frames == 8);
    CHECK(d.crc_errors >= 1 && d.garbage >= 1);
    /* a length above 64 is corruption */
    uint8_t bad[8] = {0xA5, 0x5A, 0x80, 0, 0, 65, 0, 0};
    frame_decoder_init(&d);
    for (int i = 0; i < 8; i++) frame_decoder_feed(&d, bad[i], &f);
    CHECK(d.crc_errors == 1);
}

static void test_session(void)
{
    board_t b;
    fresh(&b, RESET_POWER_ON);
    CHECK(b.dac_dirty && b.dac[0] == 2048 && b.dac[1] == 2047);      /* safe at power-up */
    board_inputs_t in = inputs(410, 410);
    ticks(&b, 10, &in);
    CHECK(n_sent == 0);                                              /* silent before HELLO */
    hello(&b, 1);
    const sent_t *ack = last(T_HELLO_ACK);
    CHECK(ack && ack->length == 7 && ack->payload[0] == 1 && ack->payload[1] == PROTO_MINOR);
    CHECK(ack && get_u16(ack->payload + 2) == 1000 && ack->payload[4] == 12 && ack->payload[6] == 7);
    ticks(&b, 100, &in);
    CHECK(count(T_SAMPLE) == 100);
    CHECK(count(T_DEVICE_HEARTBEAT) == 1);
    const sent_t *s = last(T_SAMPLE);
    CHECK(s->length == 17 && get_u16(s->payload + 4) == 410 && (int32_t)(s->payload[8] |
          s->payload[9] << 8 | s->payload[10] << 16 | (uint32_t)s->payload[11] << 24) == -42);
    CHECK(get_u16(s->payload + 15) == 1200 && get_u16(s->payload + 12) == 2048);
    CHECK(b.dac[0] == 2048);                                         /* safe until COMMAND */
    command(&b, 1000, 4000);
    CHECK(b.dac[0] == 1000 && b.dac[1] == 3000 && b.clipped == 1);   /* clipped to cmd_max */
    /* communication loss: vent after 250 ms, cleared by the next COMMAND */
    ticks(&b, 250, &in);
    CHECK(b.dac[0] == 1000 && !b.comm_lost);
    ticks(&b, 1, &in);
    CHECK(b.comm_lost && b.watchdog_trips == 1 && b.dac[0] == 2048 && b.dac[1] == 2047);
    CHECK(last(T_SAMPLE)->payload[14] & ST_VENTED);
    host(&b, T_HEARTBEAT, NULL, 0);                                  /* not a command: stays */
    CHECK(b.dac[0] == 2048);
    command(&b, 1100, 1200);
    CHECK(!b.comm_lost && b.dac[0] == 1100 && b.dac[1] == 1200);
    /* silence for 1 s: streaming stops */
    ticks(&b, 1001, &in);
    CHECK(!b.streaming);
    int samples = count(T_SAMPLE);
    ticks(&b, 5, &in);
    CHECK(count(T_SAMPLE) == samples);
    /* another major version: answered, not streamed */
    hello(&b, 2);
    CHECK(last(T_HELLO_ACK)->payload[0] == 1 && !b.streaming);
    /* garbage, a false SYNC and a corrupted COMMAND before a true one, through the board's
     * inline fast path: only the true COMMAND is applied */
    hello(&b, 1);
    uint8_t out[FRAME_MAX], p[4];
    put_u16(p, 3333);
    put_u16(p + 2, 2222);
    uint8_t n = frame_encode(out, T_COMMAND, 7, p, 4);
    const uint8_t junk[3] = {0x00, 0xA5, 0x5A};
    for (int i = 0; i < 3; i++) board_rx_byte(&b, junk[i]);
    out[8] ^= 0xFF;
    for (uint8_t i = 0; i < n; i++) board_rx_byte(&b, out[i]);
    CHECK(b.dac[0] == 2048);                                         /* the new session: safe */
    out[8] ^= 0xFF;
    for (int k = 0; k < 6; k++)
        for (uint8_t i = 0; i < n; i++) board_rx_byte(&b, out[i]);
    CHECK(b.dac[0] == 3333 && b.dac[1] == 2222 && b.rx.crc_errors >= 1);
    /* a burst of 50 COMMANDs back to back, the 20th with a wrong CRC: the fast path (CRC kept
     * per byte, frames handled in place) takes every good one, the bad one is counted */
    uint32_t frames_before = b.host_frames, errors_before = b.rx.crc_errors;
    for (uint16_t k = 0; k < 50; k++) {
        put_u16(p, (uint16_t)(1000 + k));
        put_u16(p + 2, (uint16_t)(3000 - k));
        n = frame_encode(out, T_COMMAND, (uint16_t)(100 + k), p, 4);
        if (k == 19)
            out[n - 1] ^= 0x01;
        for (uint8_t i = 0; i < n; i++) board_rx_byte(&b, out[i]);
        if (k == 18 || k == 19)
            CHECK(b.dac[0] == 1018 && b.dac[1] == 2982);             /* 19 not applied */
    }
    CHECK(b.dac[0] == 1049 && b.dac[1] == 2951 && b.rx.n == 0);
    CHECK(b.host_frames - frames_before == 49 && b.rx.crc_errors - errors_before == 1);
    /* unknown frame type: a protocol error, ignored */
    host(&b, 0x42, NULL, 0);
    CHECK(b.protocol_errors == 1);
}

static void test_latched_faults(void)
{
    board_t b;
    fresh(&b, RESET_POWER_ON);
    board_inputs_t in = inputs(1000, 1000);
    hello(&b, 1);
    command(&b, 3000, 500);
    ticks(&b, 3, &in);
    CHECK(b.dac[0] == 3000);
    in.estop = 1;
    ticks(&b, 1, &in);
    CHECK(b.faults == FAULT_ESTOP && b.dac[0] == 2048);
    CHECK((last(T_SAMPLE)->payload[14] & (ST_VENTED | ST_FAULT | ST_ESTOP)) == 7);
    command(&b, 3000, 500);                                          /* ignored while latched */
    CHECK(b.dac[0] == 2048);
    host(&b, T_ARM, NULL, 0);                                        /* cause still present */
    CHECK(b.faults == FAULT_ESTOP);
    in.estop = 0;
    ticks(&b, 1, &in);
    command(&b, 3000, 500);
    CHECK(b.dac[0] == 2048);                                         /* released, not re-armed */
    host(&b, T_ARM, NULL, 0);
    CHECK(b.faults == 0 && b.dac[0] == 2048);                        /* safe until a COMMAND */
    command(&b, 3000, 500);
    CHECK(b.dac[0] == 3000);
    /* over-pressure: 5 samples in a row above the limit */
    board_inputs_t high = inputs(3700, 1000);
    ticks(&b, 4, &high);
    ticks(&b, 1, &in);
    CHECK(b.faults == 0);
    ticks(&b, 5, &high);
    CHECK(b.faults == FAULT_OVERPRESSURE && b.dac[0] == 2048);
    host(&b, T_ARM, NULL, 0);
    CHECK(b.faults == FAULT_OVERPRESSURE);
    ticks(&b, 1, &in);
    host(&b, T_ARM, NULL, 0);
    CHECK(b.faults == 0);
    /* a watchdog reset is latched until ARM */
    fresh(&b, RESET_WATCHDOG);
    hello(&b, 1);
    command(&b, 3000, 500);
    CHECK(b.faults == FAULT_WATCHDOG_RESET && b.dac[0] == 2048);
    ticks(&b, 100, &in);
    const sent_t *h = last(T_DEVICE_HEARTBEAT);
    CHECK(h && h->length == 32 && h->payload[13] == FAULT_WATCHDOG_RESET && h->payload[14] == RESET_WATCHDOG);
    host(&b, T_ARM, NULL, 0);
    command(&b, 3000, 500);
    CHECK(b.faults == 0 && b.dac[0] == 3000);
}

static void test_calibration(void)
{
    calib_t c;
    calib_defaults(&c);
    CHECK(calib_valid(&c));
    uint8_t bytes[CALIB_SIZE];
    calib_to_bytes(&c, bytes);
    bytes[10] ^= 1;                                                  /* a flipped EEPROM bit */
    calib_t d;
    calib_from_bytes(&d, bytes);
    CHECK(!calib_valid(&d));
    board_t b;
    board_init(&b, &d, RESET_POWER_ON, tx, store, NULL);
    CHECK(b.cal_defaulted && b.cal.safe_code[0] == 0 && calib_valid(&b.cal));
    /* zero and gain */
    c.zero_offset[0] = 20;
    c.gain_q14[0] = CALIB_GAIN_ONE + CALIB_GAIN_ONE / 4;
    calib_seal(&c);
    CHECK(calib_pressure(&c, 0, 430) == 410);
    CHECK(calib_pressure(&c, 0, 430 + 400) == 410 + 500);
    CHECK(calib_pressure(&c, 0, 0) == 0 && calib_pressure(&c, 0, 4095) == 4095);
    /* CAL_WRITE: refused while commanding, stored when safe, invalid rejected */
    fresh(&b, RESET_POWER_ON);
    hello(&b, 1);
    command(&b, 100, 100);
    calib_t w = b.cal;
    w.safe_code[0] = 1234;
    calib_to_bytes(&w, bytes);
    host(&b, T_CAL_WRITE, bytes, CALIB_SIZE - 2);
    CHECK(last(T_CAL)->payload[0] == CAL_NOT_SAFE);
    hello(&b, 1);                                                    /* new session: safe */
    stores = 0;
    host(&b, T_CAL_WRITE, bytes, CALIB_SIZE - 2);
    CHECK(last(T_CAL)->payload[0] == CAL_OK && stores == 1 && stored.safe_code[0] == 1234);
    CHECK(b.dac[0] == 1234 && calib_valid(&stored));
    w.cmd_min[1] = 3500;                                             /* min > max (3000) */
    calib_to_bytes(&w, bytes);
    host(&b, T_CAL_WRITE, bytes, CALIB_SIZE - 2);
    CHECK(last(T_CAL)->payload[0] == CAL_INVALID && stores == 1);
    host(&b, T_CAL_READ, NULL, 0);
    calib_from_bytes(&d, last(T_CAL)->payload + 1);
    CHECK(calib_valid(&d) && d.safe_code[0] == 1234);
    /* auto-zero while vented: offsets from 256 samples, stored */
    board_inputs_t in = inputs(425, 400);
    host(&b, T_ZERO, NULL, 0);
    CHECK(last(T_CAL)->payload[0] == CAL_STARTED && b.zero_left == ZERO_SAMPLES);
    command(&b, 3000, 3000);                                         /* ignored while zeroing */
    ticks(&b, ZERO_SAMPLES, &in);
    CHECK(last(T_CAL)->payload[0] == CAL_OK && stores == 2);
    CHECK(stored.zero_offset[0] == 15 && stored.zero_offset[1] == -10 && calib_valid(&stored));
    ticks(&b, 1, &in);
    CHECK(get_u16(last(T_SAMPLE)->payload + 4) == 410);
    CHECK(b.dac[0] == 1234);                      /* the silence vented the held command */
    command(&b, 3000, 3000);
    CHECK(b.dac[0] == 3000);
    /* refused while commanding; refused when the muscles are not at atmosphere */
    host(&b, T_ZERO, NULL, 0);
    CHECK(last(T_CAL)->payload[0] == CAL_NOT_SAFE);
    hello(&b, 1);
    board_inputs_t pressurised = inputs(1500, 410);
    host(&b, T_ZERO, NULL, 0);
    ticks(&b, ZERO_SAMPLES, &pressurised);
    CHECK(last(T_CAL)->payload[0] == CAL_NOT_VENTED && stores == 2);
}

int main(void)
{
    test_crc_and_frames();
    test_session();
    test_latched_faults();
    test_calibration();
    printf("firmware core: %d checks, %d failed\n", checks, failures);
    return failures ? 1 : 0;
}
