/* The board's side of PROTOCOL.md and its safety, without hardware: the HAL calls
 * board_rx_byte() for every received byte and board_tick() once per sample period with the inputs
 * sampled by the timer interrupt; the board answers through the tx callback and leaves the valve
 * codes to apply in dac[] (dac_dirty set when they changed).
 *
 * Safe states (both valves at calib.safe_code): power-up and every reset until the first COMMAND
 * of a session; communication loss (no valid host frame for COMM_LOSS_MS: cleared by the next
 * COMMAND, as PROTOCOL.md step 5); latched faults (e-stop input, over-pressure, a watchdog reset):
 * COMMANDs are ignored until an ARM frame while the cause is gone. */
#ifndef PAM_BOARD_H
#define PAM_BOARD_H
#include <stdint.h>

#include "calib.h"
#include "frame.h"

#ifndef PROTO_MAJOR                     /* -DPROTO_MAJOR=2: a board of another major version (tests) */
#define PROTO_MAJOR 1u
#endif
#define PROTO_MINOR 2u                  /* 1.2: ARM, ZERO, CAL frames, heartbeat counters */
#define SAMPLE_RATE_HZ 1000u
#define COMM_LOSS_MS 250u
#define STREAM_STOP_MS 1000u
#define HEARTBEAT_EVERY 100u            /* samples: 10 Hz */
#define ZERO_SAMPLES 256u

enum {                                  /* frame types */
    T_HELLO = 0x01, T_COMMAND = 0x02, T_HEARTBEAT = 0x03, T_ARM = 0x04, T_ZERO = 0x05,
    T_CAL_WRITE = 0x06, T_CAL_READ = 0x07,
    T_SAMPLE = 0x80, T_HELLO_ACK = 0x81, T_DEVICE_HEARTBEAT = 0x83, T_CAL = 0x86,
};
enum {                                  /* SAMPLE status and DEVICE_HEARTBEAT state bits */
    ST_VENTED = 0x01,                   /* the valves are at the safe output by the board's will */
    ST_FAULT = 0x02,                    /* a latched fault (1.2) */
    ST_ESTOP = 0x04,                    /* the e-stop input is active (1.2) */
    ST_ZEROING = 0x08,                  /* an auto-zero is running (1.2) */
};
enum {                                  /* latched fault causes (bits) */
    FAULT_ESTOP = 0x01, FAULT_OVERPRESSURE = 0x02, FAULT_WATCHDOG_RESET = 0x04,
};
enum {                                  /* CAL result byte */
    CAL_OK = 0, CAL_INVALID = 1, CAL_NOT_SAFE = 2, CAL_NOT_VENTED = 3, CAL_STARTED = 4,
};
enum {                                  /* reset causes (the HAL's, passed to board_init) */
    RESET_POWER_ON = 0x01, RESET_EXTERNAL = 0x02, RESET_BROWN_OUT = 0x04, RESET_WATCHDOG = 0x08,
};

typedef struct {
    uint16_t adc[4];                    /* raw ADC counts: P1, P2, torque, P_supply */
    int32_t encoder;                    /* quadrature counts */
    uint8_t estop;                      /* 1: the e-stop input is active */
} board_inputs_t;

/* A frame to send: bytes[0..n) are its header and payload; the HAL sends them followed by the
 * CRC-16 of bytes[2..n), little-endian (on the AVR computed while copying to the TX ring: one
 * pass over the bytes). */
typedef void (*board_tx_t)(const uint8_t *bytes, uint8_t n, void *ctx);
typedef void (*board_store_t)(const calib_t *c, void *ctx);     /* write to EEPROM */

typedef struct {
    calib_t cal;
    uint8_t cal_defaulted;              /* the stored calibration was invalid: defaults used */
    frame_decoder_t rx;
    board_tx_t tx;
    board_store_t store;
    void *ctx;
    uint16_t seq;
    uint32_t tick;
    uint8_t heartbeat_in;               /* samples since the last DEVICE_HEARTBEAT */
    uint8_t heartbeat_due;              /* board_send_heartbeat has one to send */
    uint16_t ms_since_host;             /* sample periods since the last valid host frame */
    uint8_t streaming;
    uint8_t commanded;                  /* a COMMAND applied in this session */
    uint8_t comm_lost;
    uint8_t faults;                     /* latched FAULT_* */
    uint8_t over_count;
    uint8_t estop_now;                  /* the e-stop input at the last tick */
    uint8_t reset_cause;
    uint16_t cmd[2];                    /* the host's (clipped) command */
    uint16_t dac[2];                    /* what the valves get */
    uint8_t dac_dirty;
    uint16_t zero_left;                 /* auto-zero: samples still to average */
    int32_t zero_sum[CALIB_CHANNELS];
    /* counters (DEVICE_HEARTBEAT) */
    uint32_t host_frames;
    uint32_t watchdog_trips;            /* communication-loss vents */
    uint32_t clipped;
    uint16_t overruns;                  /* set by the HAL */
    uint16_t worst_tick_us;             /* set by the HAL */
    uint16_t uart_errors;               /* set by the HAL */
    uint16_t protocol_errors;
} board_t;

void board_init(board_t *b, const calib_t *stored, uint8_t reset_cause, board_tx_t tx,
                board_store_t store, void *ctx);
void board_rx_frame_end(board_t *b, uint8_t pushed);   /* the slow path of board_rx_byte */

/* One received byte (inline: on the AVR every received byte passes here, 1 kHz COMMANDs are
 * 12 kB/s, a burst of them 100 kB/s): appended and the CRC kept (frame_decoder_push); a complete
 * frame is handled in place. */
static inline void board_rx_byte(board_t *b, uint8_t byte)
{
    uint8_t pushed = frame_decoder_push(&b->rx, byte);
    if (pushed != FRAME_MORE)
        board_rx_frame_end(b, pushed);
}
void board_tick(board_t *b, const board_inputs_t *in);
/* The DEVICE_HEARTBEAT (10 Hz) that board_tick made due, if any, with the counters and state of
 * now; called by the HAL after board_tick, at a moment of its choice within the tick period (the
 * AVR: late in the period, so that the heartbeat's bytes on the line share two periods' CPU). */
void board_send_heartbeat(board_t *b);
uint8_t board_status(const board_t *b);

/* The valves are at the safe output. */
static inline uint8_t board_safe(const board_t *b)
{
    return b->faults || b->comm_lost || !b->commanded || b->zero_left;
}

#endif
