/* The reference DAQ board on an ATmega2560 (Arduino Mega 2560, 16 MHz): the thin hardware layer
 * under the portable core (core/board.c). Pins and parts: WIRING.md.
 *
 *   Timer1 CTC 1 kHz  compare A ISR: reads the 4 ADC channels (MCP3208 on SPI, 2 MHz), the
 *                     encoder count and the e-stop pin into a snapshot, flags a tick (overrun
 *                     counted if the previous one was not consumed); compare B (0.8 ms): the
 *                     moment to send a heartbeat due (its bytes then share two tick periods),
 *                     in a period that has received no frame yet (at most 20 ms late);
 *   INT4/INT5         encoder A/B, any edge: x4 quadrature decoding;
 *   USART0 1 Mbaud    (U2X, UBRR 1: exact) RX and UDRE interrupts over two 256-byte rings,
 *                     hand-written (no SREG change on their usual path);
 *   main loop         sleeps until an ISR flags work in GPIOR0 (the RX ISR: once a whole frame
 *                     is in); feeds received frames to the core whole (a tick waiting goes
 *                     first), writes a COMMAND to the MCP4922 at once if it is the period's
 *                     first, the newest of a burst at the next tick; runs the core's tick,
 *                     resets the watchdog.
 * The watchdog (30 ms, system-reset mode) is reset only by the main loop after a tick: a hung
 * loop or a dead timer resets the board into its safe output. Cycle counts: README.md. */
#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <avr/wdt.h>
#include <util/atomic.h>

#include "../core/board.h"
#include "../core/crc16.h"

#define UART_RX_SIZE 256u                /* 8-bit indices wrap by themselves */
#define UART_TX_SIZE 256u

/* ---- pins (PORTB: SPI and chip selects) ------------------------------------------------------- */
#define ADC_CS PB0                      /* D53 (SS, an output: SPI master) */
#define SCK PB1                         /* D52 */
#define MOSI PB2                        /* D51 */
#define DAC_CS PB4                      /* D10 */
#define DAC_LDAC PB5                    /* D11 */
#define LED PB7                         /* D13: on while the board holds the safe output */
#define ESTOP PA0                       /* D22: NC contact to GND, pull-up: high = e-stop */

static board_t board;
static calib_t EEMEM ee_calib;
uint8_t mcusr_at_reset __attribute__((section(".noinit")));

/* The rings are 256-byte aligned: an 8-bit index is the low byte of the address (the ISRs load
 * the high byte as a constant) and wraps by itself. */
static volatile uint8_t rx_ring[UART_RX_SIZE] __attribute__((aligned(256)));
static volatile uint8_t rx_head, rx_tail;
static volatile uint8_t rx_wake = FRAME_HEADER; /* the RX ISR sets WORK_RX when rx_head reaches
                                         * it: the main loop waits for a whole frame (rx_drain) */
static volatile uint8_t tx_ring[UART_TX_SIZE] __attribute__((aligned(256)));
static volatile uint8_t tx_head, tx_tail;
static volatile uint8_t uart_errors;    /* wraps: the main loop accumulates it */

/* The main loop's work flags in GPIOR0 (sbi/cbi/sbic: single instructions, no SREG): set by the
 * ISRs, the main loop sleeps while both are clear */
#define WORK_RX 0                       /* bytes in the RX ring */
#define WORK_TICK 1                     /* a sampled tick to process */
#define WORK_HEARTBEAT 2                /* 0.8 ms into the period: the heartbeat's moment */
#define WORK (_BV(WORK_RX) | _BV(WORK_TICK) | _BV(WORK_HEARTBEAT))
#define UCSR0B_IDLE (_BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0))
#define UCSR0B_SENDING (UCSR0B_IDLE | _BV(UDRIE0))

static volatile int32_t encoder;
static volatile uint8_t enc_state;
static volatile board_inputs_t snapshot;
static volatile uint16_t overruns;
static uint8_t uart_errors_seen;
#define HEARTBEAT_WAIT 20u              /* tick periods a heartbeat due may wait for a quiet one */
static uint8_t heartbeat_waited;

/* Reset cause, then the watchdog off before anything else (it stays on after a watchdog reset). */
void early_init(void) __attribute__((naked, used, section(".init3")));
void early_init(void)
{
    mcusr_at_reset = MCUSR;
    MCUSR = 0;
    wdt_disable();
}

/* ---- UART --------------------------------------------------------------------------------------- */
/* The UART ISRs' own registers: r2:r3 keep Z while an ISR uses it, r4 carries its byte. The whole
 * firmware is built with -ffixed-r2 -ffixed-r3 -ffixed-r4 (Makefile: ISR_REGS), so no other code
 * uses them, which the build checks in the linked ELF (library code included); the ISRs cannot
 * nest (neither enables interrupts). Saving Z with a movw each way costs 2 cycles where pushing
 * and popping three registers cost 12: on every byte sent or received (up to 100 a tick). */

/* A received byte into the RX ring (framing / overrun errors and a full ring counted); the main
 * loop's WORK_RX flag when the ring's head reaches rx_wake. Hand-written: 1 Mbaud is a byte every
 * 160 cycles; no instruction of the usual path changes SREG (cpse, sbrc, ld/st, sbi), so SREG is
 * saved only on the error paths. */
ISR(USART0_RX_vect, ISR_NAKED)
{
    __asm__ volatile(
        "movw r2, r30\n\t"
        "lds r4, %[ucsra]\n\t"        /* the status belongs to the byte in UDR: read first */
        "sbrc r4, %[fe]\n\t"
        "rjmp 3f\n\t"
        "sbrc r4, %[dor]\n\t"
        "rjmp 3f\n\t"
        "1: lds r30, %[head]\n\t"
        "ldi r31, hi8(%[ring])\n\t"
        "lds r4, %[udr]\n\t"
        "st Z+, r4\n\t"               /* ring[head] (a free slot even when the ring is full) */
        "lds r4, %[tail]\n\t"
        "cpse r30, r4\n\t"            /* head + 1 == tail: full, the byte is lost */
        "rjmp 2f\n\t"
        "in r31, __SREG__\n\t"
        "lds r30, %[errors]\n\t"
        "inc r30\n\t"
        "sts %[errors], r30\n\t"
        "out __SREG__, r31\n\t"
        "rjmp 4f\n\t"
        "2: sts %[head], r30\n\t"
        "lds r4, %[wake]\n\t"         /* the fill the main loop waits for: wake it */
        "cpse r30, r4\n\t"
        "rjmp 4f\n\t"
        "sbi %[gpior], %[work_rx]\n\t"
        "4: movw r30, r2\n\t"
        "reti\n\t"
        "3: in r31, __SREG__\n\t"      /* framing error or overrun: counted, the byte kept */
        "lds r30, %[errors]\n\t"
        "inc r30\n\t"
        "sts %[errors], r30\n\t"
        "out __SREG__, r31\n\t"
        "rjmp 1b\n\t"
        :: [ucsra] "n" (_SFR_MEM_ADDR(UCSR0A)), [udr] "n" (_SFR_MEM_ADDR(UDR0)),
           [fe] "n" (FE0), [dor] "n" (DOR0), [errors] "i" (&uart_errors),
           [head] "i" (&rx_head), [tail] "i" (&rx_tail), [ring] "i" (rx_ring),
           [wake] "i" (&rx_wake), [gpior] "n" (_SFR_IO_ADDR(GPIOR0)), [work_rx] "n" (WORK_RX));
}

/* One byte of the TX ring per interrupt, the firmware's hottest code (a byte every 160 cycles
 * while sending): no SREG change (ld Z+, cpse, ldi), Z kept in r2:r3. When the ring is empty
 * after this byte the interrupt is switched off by writing UCSR0B's constant (no read-modify-
 * write: uart_tx writes the other constant after it advanced tx_head). */
ISR(USART0_UDRE_vect, ISR_NAKED)
{
    __asm__ volatile(
        "movw r2, r30\n\t"
        "lds r30, %[tail]\n\t"
        "ldi r31, hi8(%[ring])\n\t"
        "ld r4, Z+\n\t"
        "sts %[udr], r4\n\t"
        "sts %[tail], r30\n\t"         /* the low byte: wraps at 256 */
        "lds r4, %[head]\n\t"
        "cpse r30, r4\n\t"
        "rjmp 1f\n\t"
        "ldi r31, %[idle]\n\t"
        "sts %[ucsrb], r31\n\t"
        "1: movw r30, r2\n\t"
        "reti\n\t"
        :: [tail] "i" (&tx_tail), [head] "i" (&tx_head), [ring] "i" (tx_ring),
           [udr] "n" (_SFR_MEM_ADDR(UDR0)), [ucsrb] "n" (_SFR_MEM_ADDR(UCSR0B)),
           [idle] "n" (UCSR0B_IDLE));
}

/* Copies n bytes from X (src) to Y (dst), each through the split CRC table of crc16.h on the way
 * (high / low: the CRC's halves): 20 cycles a byte. LOAD reads a byte from X into r24 and STORE
 * writes r24 at Y, each advancing its pointer: X+ / Y+, or for a ring's side only the low address
 * byte (the ring is 256-byte aligned: its index wraps by itself). Z is the table's address. */
#define COPY_WITH_CRC(LOAD, STORE, src, dst, n, high, low)                                       \
    __asm__ volatile(                                                                            \
        "1: " LOAD STORE                                                                         \
        "eor r24, %[hi]\n\t"                                                                     \
        "mov r30, r24\n\t"                                                                       \
        "ldi r31, hi8(%[th])\n\t"                                                                \
        "lpm %[hi], Z\n\t"                                                                       \
        "eor %[hi], %[lo]\n\t"                                                                   \
        "ldi r31, hi8(%[tl])\n\t"                                                                \
        "lpm %[lo], Z\n\t"                                                                       \
        "dec %[k]\n\t"                                                                           \
        "brne 1b\n\t"                                                                            \
        : [hi] "+r" (high), [lo] "+r" (low), [k] "+r" (n), "+x" (src), "+y" (dst)               \
        : [th] "i" (crc16_table_high), [tl] "i" (crc16_table_low)                                \
        : "r24", "r30", "r31", "memory")

/* A frame into the TX ring, its CRC-16 computed on the way (core/board.h: bytes are the header
 * and the payload; SYNC not in the CRC). Only the main loop writes tx_head and only the UDRE ISR
 * tx_tail (one byte each: atomic), so no interrupt is masked: the bytes first, then the head,
 * then UDRIE. */
static void uart_tx(const uint8_t *bytes, uint8_t n, void *ctx)
{
    (void)ctx;
    uint8_t head = tx_head;
    if ((uint8_t)(head - tx_tail) + (uint16_t)n + 2u >= UART_TX_SIZE) {
        ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
            uart_errors++;              /* the host does not read: the frame is dropped */
        }
        return;
    }
    tx_ring[head++] = *bytes++;         /* SYNC */
    tx_ring[head++] = *bytes++;
    volatile uint8_t *ring = tx_ring + head;
    n = (uint8_t)(n - 2);
    uint8_t high = 0xFF, low = 0xFF;    /* CRC16_INIT */
    /* to the ring: Y's low address byte wraps */
    COPY_WITH_CRC("ld r24, X+\n\t", "st Y, r24\n\tinc r28\n\t", bytes, ring, n, high, low);
    head = (uint8_t)(uintptr_t)ring;
    tx_ring[head++] = low;
    tx_ring[head++] = high;
    tx_head = head;
    UCSR0B = UCSR0B_SENDING;
}

/* The frame of `size` bytes at the RX ring's tail (SYNC and length checked by rx_need) into the
 * decoder's buffer in one pass, its CRC computed on the way (20 cycles a byte; the byte-wise
 * decoder, the main loop woken by every byte, took about 60 more a byte), then handled as the
 * byte-wise decoder would at the frame's last byte: board_rx_frame_end with FRAME_READY, or
 * FRAME_RESYNC on a CRC error (the decoder then resynchronises in its buffer, counting the
 * error). */
__attribute__((noinline)) static void rx_frame(uint8_t tail, uint8_t size)
{
    frame_decoder_t *d = &board.rx;
    uint8_t *buf = d->buf;
    buf[0] = FRAME_SYNC0;
    buf[1] = FRAME_SYNC1;
    const volatile uint8_t *ring = rx_ring + (uint8_t)(tail + 2);
    uint8_t *out = buf + 2;
    uint8_t n = (uint8_t)(size - 4);    /* type, seq, length and the payload: under the CRC */
    uint8_t high = 0xFF, low = 0xFF;    /* CRC16_INIT */
    /* from the ring: X's low address byte wraps */
    COPY_WITH_CRC("ld r24, X\n\tinc r26\n\t", "st Y+, r24\n\t", ring, out, n, high, low);
    out[0] = rx_ring[(uint8_t)(tail + size - 2)];
    out[1] = rx_ring[(uint8_t)(tail + size - 1)];
    d->n = size;
    d->crc = (uint16_t)((uint16_t)high << 8 | low);
    board_rx_frame_end(&board, d->crc == get_u16(out) ? FRAME_READY : FRAME_RESYNC);
}

/* The bytes the RX ring must hold from its tail before the frame that starts there can go to
 * rx_frame whole (its SYNC, header and length read as far as they are in); 0: the byte at the
 * tail goes to the byte-wise decoder (one that holds the rest of a resynchronisation, garbage,
 * a bad SYNC or length). */
static uint8_t rx_need(uint8_t tail, uint8_t avail)
{
    if (board.rx.n || rx_ring[tail] != FRAME_SYNC0)
        return 0;
    if (avail >= 2 && rx_ring[(uint8_t)(tail + 1)] != FRAME_SYNC1)
        return 0;
    if (avail < FRAME_HEADER)
        return FRAME_HEADER;
    uint8_t length = rx_ring[(uint8_t)(tail + 5)];
    return length > FRAME_MAX_PAYLOAD ? 0 : (uint8_t)(FRAME_OVERHEAD + length);
}

static void dac_write(const uint16_t code[2]);
static uint8_t dac_this_tick;           /* a COMMAND went to the DAC in this tick period */
static uint8_t frames_this_tick;        /* whole frames received in this tick period */

/* The received bytes to the core: whole frames at once, the rest byte by byte; until the ring
 * holds a whole frame the main loop sleeps (rx_wake: the RX ISR wakes it at the frame's last
 * byte, not at every byte). A COMMAND goes to the valves at once if it is this tick period's
 * first; a later one (a burst of frames: each supersedes the one before) at the next tick, the
 * newest only: at most two DAC writes a period, whatever the host sends. A tick waiting goes
 * first (a burst at the line rate): WORK_RX stays set. */
static void rx_drain(void)
{
    uint8_t tail = rx_tail;
    for (;;) {
        uint8_t avail = (uint8_t)(rx_head - tail);
        /* an empty ring: the next frame's header (every frame has one and two CRC bytes) */
        uint8_t need = avail ? rx_need(tail, avail) : FRAME_HEADER;
        if (!need) {
            board_rx_byte(&board, rx_ring[tail]);
            rx_tail = ++tail;
        } else if (avail >= need) {
            rx_frame(tail, need);
            rx_tail = tail = (uint8_t)(tail + need);
            frames_this_tick++;
        } else {
            rx_wake = (uint8_t)(tail + need);
            if ((uint8_t)(rx_head - tail) < need)   /* else the byte came before rx_wake */
                return;
            continue;
        }
        if (board.dac_dirty && !dac_this_tick) {
            board.dac_dirty = 0;
            dac_this_tick = 1;
            dac_write(board.dac);
        }
        if (GPIOR0 & _BV(WORK_TICK)) {
            GPIOR0 |= _BV(WORK_RX);
            return;
        }
    }
}

static void uart_init(void)
{
    UCSR0A = _BV(U2X0);
    UBRR0H = 0;
    UBRR0L = 1;                         /* 16 MHz / (8 * (1 + 1)) = 1 Mbaud exactly */
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00); /* 8N1 */
    UCSR0B = UCSR0B_IDLE;
}

/* ---- SPI: MCP3208 ADC (mode 0, 2 MHz) and MCP4922 DAC (mode 0, 8 MHz) --------------------------- */
static inline __attribute__((always_inline)) uint8_t spi(uint8_t out)
{
    SPDR = out;
    while (!(SPSR & _BV(SPIF)))
        ;
    return SPDR;
}

static uint16_t adc_read(uint8_t channel)
{
    SPCR = _BV(SPE) | _BV(MSTR) | _BV(SPR0);    /* fosc / 8 with SPI2X: 2 MHz */
    SPSR = _BV(SPI2X);
    PORTB &= (uint8_t)~_BV(ADC_CS);
    spi((uint8_t)(0x06 | (channel >> 2)));      /* start, single-ended, D2 */
    uint8_t high = spi((uint8_t)(channel << 6)) & 0x0F;
    uint8_t low = spi(0);
    PORTB |= _BV(ADC_CS);
    return (uint16_t)((uint16_t)high << 8 | low);
}

static void dac_write(const uint16_t code[2])
{
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {         /* the tick ISR uses the bus too */
        SPCR = _BV(SPE) | _BV(MSTR);            /* fosc / 2 with SPI2X: 8 MHz */
        SPSR = _BV(SPI2X);
        for (uint8_t ch = 0; ch < 2; ch++) {
            /* A/B, buffered Vref, gain 1x, active; 12 data bits */
            uint16_t word = (uint16_t)((ch ? 0x8000u : 0) | 0x7000u | (code[ch] & 0x0FFFu));
            PORTB &= (uint8_t)~_BV(DAC_CS);
            spi((uint8_t)(word >> 8));
            spi((uint8_t)word);
            PORTB |= _BV(DAC_CS);
        }
        PORTB &= (uint8_t)~_BV(DAC_LDAC);       /* both outputs change together */
        PORTB |= _BV(DAC_LDAC);
    }
    if (board_safe(&board))
        PORTB |= _BV(LED);
    else
        PORTB &= (uint8_t)~_BV(LED);
}

/* ---- encoder: x4 quadrature on INT4 (A, PE4) and INT5 (B, PE5) -------------------------------- */
static void encoder_edge(void)
{
    static const int8_t step[16] = {0, 1, -1, 0, -1, 0, 0, 1, 1, 0, 0, -1, 0, -1, 1, 0};
    uint8_t now = (uint8_t)((PINE >> PE4) & 0x03);
    encoder += step[(enc_state << 2) | now];
    enc_state = now;
}

ISR(INT4_vect) { encoder_edge(); }
ISR(INT5_vect, ISR_ALIASOF(INT4_vect));

/* ---- the 1 kHz tick ----------------------------------------------------------------------------- */
ISR(TIMER1_COMPA_vect)
{
    if (GPIOR0 & _BV(WORK_TICK))
        overruns++;                     /* the main loop did not consume the last tick */
    for (uint8_t ch = 0; ch < 4; ch++)
        snapshot.adc[ch] = adc_read(ch);
    snapshot.encoder = encoder;         /* INT4/5 are masked inside this ISR: consistent */
    snapshot.estop = (uint8_t)((PINA >> ESTOP) & 1);
    GPIOR0 |= _BV(WORK_TICK);
}

/* 0.8 ms into every period (Timer1 compare B): a DEVICE_HEARTBEAT due is sent now, its 40 bytes
 * on the line from 0.8 ms on, so their UDRE interrupts fall in two tick periods (the next SAMPLE
 * waits behind the heartbeat's last bytes, 0.2 ms, once in 100 samples) */
ISR(TIMER1_COMPB_vect, ISR_NAKED)
{
    __asm__ volatile("sbi %[gpior], %[bit]\n\treti\n\t"
                     :: [gpior] "n" (_SFR_IO_ADDR(GPIOR0)), [bit] "n" (WORK_HEARTBEAT));
}

static void store(const calib_t *c, void *ctx)
{
    (void)ctx;
    eeprom_update_block(c, &ee_calib, sizeof *c);
}

static uint8_t reset_cause(uint8_t mcusr)
{
    uint8_t cause = 0;
    if (mcusr & _BV(PORF)) cause |= RESET_POWER_ON;
    if (mcusr & _BV(EXTRF)) cause |= RESET_EXTERNAL;
    if (mcusr & _BV(BORF)) cause |= RESET_BROWN_OUT;
    if (mcusr & _BV(WDRF)) cause |= RESET_WATCHDOG;
    return cause;
}

int main(void)
{
    wdt_enable(WDTO_30MS);              /* first: a board that hangs anywhere resets */
    DDRB = _BV(ADC_CS) | _BV(SCK) | _BV(MOSI) | _BV(DAC_CS) | _BV(DAC_LDAC) | _BV(LED);
    PORTB = _BV(ADC_CS) | _BV(DAC_CS) | _BV(DAC_LDAC) | _BV(LED);
    DDRA &= (uint8_t)~_BV(ESTOP);
    PORTA |= _BV(ESTOP);                /* pull-up */
    DDRE &= (uint8_t)~(_BV(PE4) | _BV(PE5));
    PORTE |= _BV(PE4) | _BV(PE5);

    calib_t stored;
    eeprom_read_block(&stored, &ee_calib, sizeof stored);
    board_init(&board, &stored, reset_cause(mcusr_at_reset), uart_tx, store, 0);
    dac_write(board.dac);               /* the safe output first */
    board.dac_dirty = 0;

    enc_state = (uint8_t)((PINE >> PE4) & 0x03);
    EICRB = _BV(ISC40) | _BV(ISC50);    /* any edge */
    EIFR = _BV(INTF4) | _BV(INTF5);
    EIMSK = _BV(INT4) | _BV(INT5);
    uart_init();
    TCCR1A = 0;
    TCCR1B = _BV(WGM12) | _BV(CS11);    /* CTC, /8: 2 MHz */
    OCR1A = 1999;                       /* 1 kHz */
    OCR1B = 1599;                       /* 0.8 ms: the heartbeat's moment */
    TIMSK1 = _BV(OCIE1A) | _BV(OCIE1B);
    wdt_reset();
    set_sleep_mode(SLEEP_MODE_IDLE);
    sleep_enable();                     /* SE stays set: sleep only ever runs below */
    GPIOR0 = 0;
    sei();

    for (;;) {
        /* idle: a few cycles per interrupt (every UDRE byte wakes the loop); sei + sleep as one
         * asm statement: an interrupt that sets a flag after the check wakes the sleep */
        cli();
        if (!(GPIOR0 & WORK)) {
            __asm__ volatile("sei\n\tsleep" ::: "memory");
            continue;
        }
        sei();
        if (GPIOR0 & _BV(WORK_RX)) {
            GPIOR0 &= (uint8_t)~_BV(WORK_RX);  /* before the ring is read: a later wake sets it */
            rx_drain();
        }
        if (GPIOR0 & _BV(WORK_TICK)) {
            board_inputs_t in;
            ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
                in = *(const board_inputs_t *)&snapshot;
                GPIOR0 &= (uint8_t)~_BV(WORK_TICK);
                board.overruns = overruns;
                board.uart_errors = (uint16_t)(board.uart_errors + (uint8_t)(uart_errors -
                                                                             uart_errors_seen));
                uart_errors_seen = uart_errors;
            }
            board_tick(&board, &in);
            dac_this_tick = 0;
            frames_this_tick = 0;
            if (board.dac_dirty) {
                board.dac_dirty = 0;
                dac_write(board.dac);
            }
            uint16_t t;
            ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
                t = TCNT1;              /* 0.5 us since the tick */
                if (TIFR1 & _BV(OCF1A))
                    t = 2000;           /* beyond the period: an overrun anyway */
            }
            if (t / 2 > board.worst_tick_us)
                board.worst_tick_us = t / 2;
            wdt_reset();
        }
        if (GPIOR0 & _BV(WORK_HEARTBEAT)) {
            GPIOR0 &= (uint8_t)~_BV(WORK_HEARTBEAT);
            /* a heartbeat due goes at the moment of a period that has received no frame yet
             * (its 40 bytes cost about 1 500 cycles, a COMMAND about 1 400: the two are not
             * stacked on a period that may get another COMMAND), at most HEARTBEAT_WAIT
             * periods late */
            if (board.heartbeat_due && frames_this_tick && heartbeat_waited < HEARTBEAT_WAIT) {
                heartbeat_waited++;
            } else {
                heartbeat_waited = 0;
                board_send_heartbeat(&board);
            }
        }
    }
}
