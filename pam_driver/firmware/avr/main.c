/* The reference DAQ board on an ATmega2560 (Arduino Mega 2560, 16 MHz): the thin hardware layer
 * under the portable core (core/board.c). Pins and parts: WIRING.md.
 *
 *   Timer1 CTC 1 kHz  ISR: reads the 4 ADC channels (MCP3208 on SPI, 2 MHz), the encoder count and
 *                     the e-stop pin into a snapshot, flags a tick (overrun counted if the previous
 *                     one was not consumed);
 *   INT4/INT5         encoder A/B, any edge: x4 quadrature decoding;
 *   USART0 1 Mbaud    (U2X, UBRR 1: exact) RX and UDRE interrupts over two rings;
 *   main loop         feeds received bytes to the core (a COMMAND updates the MCP4922 at once),
 *                     runs the core's tick, writes the DAC, resets the watchdog, sleeps.
 * The watchdog (30 ms, system-reset mode) is reset only by the main loop after a tick: a hung
 * loop or a dead timer resets the board into its safe output. */
#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <avr/wdt.h>
#include <util/atomic.h>

#include "../core/board.h"

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

static volatile uint8_t rx_ring[UART_RX_SIZE];
static volatile uint8_t rx_head, rx_tail;
static volatile uint8_t tx_ring[UART_TX_SIZE];
static volatile uint8_t tx_head, tx_tail;
static volatile uint8_t uart_errors;    /* wraps: the main loop accumulates it */

static volatile int32_t encoder;
static volatile uint8_t enc_state;
static volatile board_inputs_t snapshot;
static volatile uint8_t tick_pending;
static volatile uint16_t overruns;
static uint8_t uart_errors_seen;

/* Reset cause, then the watchdog off before anything else (it stays on after a watchdog reset). */
void early_init(void) __attribute__((naked, used, section(".init3")));
void early_init(void)
{
    mcusr_at_reset = MCUSR;
    MCUSR = 0;
    wdt_disable();
}

/* ---- UART --------------------------------------------------------------------------------------- */
/* A received byte into the RX ring; framing / overrun errors and a full ring are counted.
 * Naked like the UDRE ISR (1 kHz COMMANDs: 12 000 of these a second). */
ISR(USART0_RX_vect, ISR_NAKED)
{
    __asm__ volatile(
        "push r24\n\t"
        "in r24, __SREG__\n\t"
        "push r24\n\t"
        "push r25\n\t"
        "push r30\n\t"
        "push r31\n\t"
        "lds r24, %[ucsra]\n\t"
        "lds r25, %[udr]\n\t"
        "andi r24, %[errs]\n\t"
        "breq 1f\n\t"
        "lds r24, %[errors]\n\t"
        "inc r24\n\t"
        "sts %[errors], r24\n\t"
        "1: lds r30, %[head]\n\t"
        "mov r24, r30\n\t"
        "inc r24\n\t"
        "lds r31, %[tail]\n\t"
        "cp r24, r31\n\t"
        "brne 2f\n\t"
        "lds r24, %[errors]\n\t"       /* ring full: the byte is lost */
        "inc r24\n\t"
        "sts %[errors], r24\n\t"
        "rjmp 3f\n\t"
        "2: ldi r31, 0\n\t"
        "subi r30, lo8(-(%[ring]))\n\t"
        "sbci r31, hi8(-(%[ring]))\n\t"
        "st Z, r25\n\t"
        "sts %[head], r24\n\t"
        "3: pop r31\n\t"
        "pop r30\n\t"
        "pop r25\n\t"
        "pop r24\n\t"
        "out __SREG__, r24\n\t"
        "pop r24\n\t"
        "reti\n\t"
        :: [ucsra] "n" (_SFR_MEM_ADDR(UCSR0A)), [udr] "n" (_SFR_MEM_ADDR(UDR0)),
           [errs] "n" (_BV(FE0) | _BV(DOR0)), [errors] "i" (&uart_errors),
           [head] "i" (&rx_head), [tail] "i" (&rx_tail), [ring] "i" (rx_ring));
}

/* One byte of the TX ring per interrupt: 1 Mbaud is a byte every 160 cycles, so this ISR is the
 * firmware's hottest code; naked, it saves 4 registers instead of gcc's 8 (the ring is 256 bytes:
 * the 8-bit index wraps by itself). */
ISR(USART0_UDRE_vect, ISR_NAKED)
{
    __asm__ volatile(
        "push r24\n\t"
        "in r24, __SREG__\n\t"
        "push r24\n\t"
        "push r30\n\t"
        "push r31\n\t"
        "lds r30, %[tail]\n\t"
        "lds r24, %[head]\n\t"
        "cp r30, r24\n\t"
        "breq 1f\n\t"
        "ldi r31, 0\n\t"
        "subi r30, lo8(-(%[ring]))\n\t"
        "sbci r31, hi8(-(%[ring]))\n\t"
        "ld r24, Z\n\t"
        "sts %[udr], r24\n\t"
        "lds r24, %[tail]\n\t"
        "inc r24\n\t"
        "sts %[tail], r24\n\t"
        "rjmp 2f\n\t"
        "1: lds r24, %[ucsrb]\n\t"
        "andi r24, %[not_udrie]\n\t"
        "sts %[ucsrb], r24\n\t"
        "2: pop r31\n\t"
        "pop r30\n\t"
        "pop r24\n\t"
        "out __SREG__, r24\n\t"
        "pop r24\n\t"
        "reti\n\t"
        :: [tail] "i" (&tx_tail), [head] "i" (&tx_head), [ring] "i" (tx_ring),
           [udr] "n" (_SFR_MEM_ADDR(UDR0)), [ucsrb] "n" (_SFR_MEM_ADDR(UCSR0B)),
           [not_udrie] "n" ((uint8_t)~_BV(UDRIE0)));
}

static void uart_tx(const uint8_t *bytes, uint8_t n, void *ctx)
{
    (void)ctx;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        if ((uint8_t)(tx_head - tx_tail) + (uint16_t)n >= UART_TX_SIZE) {
            uart_errors++;              /* the host does not read: the frame is dropped */
        } else {
            for (uint8_t i = 0; i < n; i++)
                tx_ring[(uint8_t)(tx_head + i)] = bytes[i];
            tx_head = (uint8_t)(tx_head + n);
            UCSR0B |= _BV(UDRIE0);
        }
    }
}

static void uart_init(void)
{
    UCSR0A = _BV(U2X0);
    UBRR0H = 0;
    UBRR0L = 1;                         /* 16 MHz / (8 * (1 + 1)) = 1 Mbaud exactly */
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00); /* 8N1 */
    UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
}

/* ---- SPI: MCP3208 ADC (mode 0, 2 MHz) and MCP4922 DAC (mode 0, 8 MHz) --------------------------- */
static uint8_t spi(uint8_t out)
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
    if (tick_pending)
        overruns++;                     /* the main loop did not consume the last tick */
    for (uint8_t ch = 0; ch < 4; ch++)
        snapshot.adc[ch] = adc_read(ch);
    snapshot.encoder = encoder;         /* INT4/5 are masked inside this ISR: consistent */
    snapshot.estop = (uint8_t)((PINA >> ESTOP) & 1);
    tick_pending = 1;
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
    TIMSK1 = _BV(OCIE1A);
    wdt_reset();
    set_sleep_mode(SLEEP_MODE_IDLE);
    sei();

    for (;;) {
        while (rx_tail != rx_head) {
            uint8_t byte = rx_ring[rx_tail];
            rx_tail = (uint8_t)(rx_tail + 1);
            board_rx_byte(&board, byte);
            if (board.dac_dirty) {      /* a COMMAND: to the valves now */
                board.dac_dirty = 0;
                dac_write(board.dac);
            }
        }
        if (tick_pending) {
            board_inputs_t in;
            ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
                in = *(const board_inputs_t *)&snapshot;
                tick_pending = 0;
                board.overruns = overruns;
                board.uart_errors = (uint16_t)(board.uart_errors + (uint8_t)(uart_errors -
                                                                             uart_errors_seen));
                uart_errors_seen = uart_errors;
            }
            board_tick(&board, &in);
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
        cli();
        if (!tick_pending && rx_tail == rx_head) {
            sleep_enable();
            sei();
            sleep_cpu();
            sleep_disable();
        }
        sei();
    }
}
