/* pam-board-sim: the reference board's ELF on simavr's ATmega2560, wired to a simulated joint.
 *
 *   pam-board-sim FIRMWARE.elf [--link PATH] [--status-file PATH] [--duration S]
 *                 [--eeprom PATH] -- PLANT ARGV...
 *
 * The board's USART0 is bridged to a pseudo-terminal of our own (posix_openpt; --link keeps a
 * symlink to its slave like pam-emulator's) at the line's byte rate; the MCP3208 ADC and the
 * MCP4922 DAC are emulated on the SPI bus (chip selects PB0 / PB4, LDAC PB5); the encoder's A/B
 * lines (PE4/PE5) are stepped through quadrature states; the e-stop input is PA0. The plant is a
 * child process (PLANT ARGV, e.g. sim/plant.py) exchanging, once per simulated millisecond, the
 * valve voltages after the op-amp stage (2 doubles) for the analog inputs and the encoder count
 * (4 doubles: P1, P2, torque, P_supply volts; 1 int64 count). Simulated time is paced to the wall
 * clock (the host expects a real-time board).
 *
 * simavr 1.6 workarounds (README.md): its SPI completes every byte after a fixed 100 us whatever
 * the clock (the harness replaces the SPDR write handler and completes a byte after 8 SPI clocks);
 * its UART prints to stdout and sleeps in status polls unless the STDIO / POLL_SLEEP flags are
 * cleared, and counts 11 bits per byte; its uart_pty part stalls (not used: our own pty bridge);
 * a watchdog reset clears the cycle timers and the pin levels (the harness re-drives its pins
 * after a reset).
 *
 * Control on stdin, one command a line: "estop 0|1", "spi_stall MS" (the SPI bus stops answering
 * for MS: the firmware hangs in its SPI wait and the watchdog must reset it), "unplug MS" (pty
 * closed, link removed, a new pty after MS), "stats" (the JSON status on stdout).
 * --eeprom PATH: the board's 4 KiB EEPROM image, loaded at start when the file exists and saved
 * every 100 ms and at exit (a board keeps its calibration across power cycles).
 * The JSON status (--status-file, rewritten every 100 ms and at exit) has the measurements. */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <avr_eeprom.h>
#include <avr_extint.h>
#include <avr_ioport.h>
#include <avr_spi.h>
#include <avr_uart.h>
#include <sim_avr.h>
#include <sim_elf.h>
#include <sim_io.h>

#include "../core/frame.h"

#define F_CPU 16000000u
#define CYCLES_PER_MS (F_CPU / 1000u)
#define LINE_BYTE_CYCLES 160u           /* 10 bits at 1 Mbaud */
#define SPDR_ADDR 0x4E
#define SPSR_ADDR 0x4D
#define SPCR_ADDR 0x4C
#define PORTB_ADDR 0x25
#define TYPE_COMMAND 0x02
#define MAX_LAG_NS 20000000ull           /* 20 ms */
#define TICK_VECTOR 0x44                /* TIMER1_COMPA (vector 17): the 1 kHz tick's entry */

static avr_t *avr;
static volatile sig_atomic_t stop;
static uint64_t wall_start;             /* wall time (ns) of simulated ms 0; moves with dropped lag */

static uint64_t now_ns(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint64_t)t.tv_sec * 1000000000ull + (uint64_t)t.tv_nsec;
}

/* ---- pty ---------------------------------------------------------------------------------------- */
static int pty_master = -1, pty_slave = -1;
static char pty_path[128];
static const char *link_path;
static uint8_t out_buf[1 << 16];
static size_t out_len;
static uint8_t in_buf[4096];
static size_t in_len, in_pos;
static uint64_t unplug_until_ms;

static void pty_open(void)
{
    pty_master = posix_openpt(O_RDWR | O_NOCTTY);
    if (pty_master < 0 || grantpt(pty_master) || unlockpt(pty_master)) {
        perror("pam-board-sim: posix_openpt");
        exit(2);
    }
    snprintf(pty_path, sizeof pty_path, "%s", ptsname(pty_master));
    pty_slave = open(pty_path, O_RDWR | O_NOCTTY);   /* kept open: the host may come and go */
    struct termios t;
    tcgetattr(pty_slave, &t);
    cfmakeraw(&t);
    tcsetattr(pty_slave, TCSANOW, &t);
    fcntl(pty_master, F_SETFL, fcntl(pty_master, F_GETFL) | O_NONBLOCK);
    if (link_path) {
        char tmp[512];
        snprintf(tmp, sizeof tmp, "%s.tmp%d", link_path, (int)getpid());
        unlink(tmp);
        if (symlink(pty_path, tmp) || rename(tmp, link_path))
            perror("pam-board-sim: link");
    }
    if (link_path)
        printf("pam-board-sim: device: %s (link %s)\n", pty_path, link_path);
    else
        printf("pam-board-sim: device: %s\n", pty_path);
    fflush(stdout);
}

static void pty_close(void)
{
    if (link_path)
        unlink(link_path);
    close(pty_master);
    close(pty_slave);
    pty_master = pty_slave = -1;
    out_len = in_len = in_pos = 0;
}

/* ---- measurements --------------------------------------------------------------------------------- */
static struct {
    uint64_t ms;                        /* simulated milliseconds */
    uint64_t ticks, busy_worst, busy_total; /* cycles executing (not asleep) per tick period */
    uint64_t busy_hist[CYCLES_PER_MS / 100 + 1];   /* tick periods per 100-cycle bin */
    uint64_t over_half;                 /* tick periods busy more than half the period */
    uint64_t tx_bytes, rx_bytes, dropped_tx;
    uint64_t cmd_frames, cmd_delays, cmd_delay_worst, cmd_delay_sum;   /* cycles */
    uint64_t dac_updates, late_ms, worst_lag_us, dropped_lag_ms, resets;
    double dac_volts[2];
    uint16_t dac_code[2];
    int estop, spi_stall_left;
} st;
static frame_decoder_t host_frames;     /* the host's bytes, decoded to time the COMMANDs */
static uint64_t cmd_done_cycle;          /* the last COMMAND byte's stop bit (0: none pending) */

/* ---- UART bridge -------------------------------------------------------------------------------- */
static void uart_out(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq; (void)param;
    st.tx_bytes++;
    if (out_len < sizeof out_buf)
        out_buf[out_len++] = (uint8_t)value;
    else
        st.dropped_tx++;
}

static void uart_flush(void)
{
    if (pty_master < 0 || !out_len)
        return;
    ssize_t n = write(pty_master, out_buf, out_len);
    if (n > 0) {
        memmove(out_buf, out_buf + n, out_len - (size_t)n);
        out_len -= (size_t)n;
    }
    if (out_len > sizeof out_buf / 2) {     /* the host does not read: a board's bytes go on */
        st.dropped_tx += out_len;
        out_len = 0;
    }
}

static uint64_t next_rx_cycle;
/* The board's clock is the wall clock (the simulation is paced to it): bytes the host wrote while
 * the simulation lagged behind must not reach the board before the simulated time at which they
 * were written, or a lag caught up would compress them into a burst at the line rate that the
 * host never sent. They were written after the previous read of the pty: in_cycle is the
 * simulated cycle of that read's wall time (the earliest they can have been written), before
 * which they are not fed. On time (the simulation ahead of the wall clock) it is in the past. */
static uint64_t in_cycle, last_read_ns;
static uint64_t wall_cycle(uint64_t ns)
{
    uint64_t t = ns > wall_start ? ns - wall_start : 0;
    return t / 1000000ull * CYCLES_PER_MS + t % 1000000ull * CYCLES_PER_MS / 1000000ull;
}

static void uart_read(void)             /* every 250 simulated us */
{
    if (pty_master < 0 || in_pos != in_len)
        return;
    ssize_t n = read(pty_master, in_buf, sizeof in_buf);
    in_pos = 0;
    in_len = n > 0 ? (size_t)n : 0;
    if (in_len)
        in_cycle = wall_cycle(last_read_ns);
    last_read_ns = now_ns();
}

static void uart_feed(void)
{
    /* one byte per byte time of the 1 Mbaud line (simavr's FIFO drains at its own 11-bit rate:
     * the pacing here keeps it from overflowing) */
    while (in_pos < in_len && avr->cycle >= next_rx_cycle && avr->cycle >= in_cycle) {
        uint8_t byte = in_buf[in_pos++];
        avr_raise_irq(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT), byte);
        st.rx_bytes++;
        next_rx_cycle = (next_rx_cycle > avr->cycle ? next_rx_cycle : avr->cycle) + 176;
        frame_t f;
        if (frame_decoder_feed(&host_frames, byte, &f) && f.type == TYPE_COMMAND) {
            st.cmd_frames++;
            cmd_done_cycle = avr->cycle + LINE_BYTE_CYCLES;
        }
    }
}

/* ---- SPI devices: MCP3208 (CS PB0) and MCP4922 (CS PB4, LDAC PB5) ------------------------------- */
static double adc_volts[8];
static uint8_t adc_idx, adc_first;
static uint8_t dac_idx, dac_bytes[2];
static uint16_t dac_input[2];
static uint8_t spi_reply;

static avr_cycle_count_t spi_done(avr_t *a, avr_cycle_count_t when, void *param)
{
    (void)when; (void)param;
    if (st.spi_stall_left)
        return when + 1000;             /* a dead bus: no SPIF until it comes back */
    avr_raise_irq(avr_io_getirq(a, AVR_IOCTL_SPI_GETIRQ(0), SPI_IRQ_INPUT), spi_reply);
    return 0;
}

static uint16_t mcp3208_code(uint8_t ch)
{
    double v = adc_volts[ch] / 5.0 * 4096.0;     /* code = 4096 Vin / Vref, Vref 5 V */
    return v <= 0 ? 0 : v >= 4095 ? 4095 : (uint16_t)v;
}

static void spdr_write(avr_t *a, avr_io_addr_t addr, uint8_t v, void *param)
{
    (void)addr; (void)param;
    a->data[SPSR_ADDR] &= (uint8_t)~0x80;       /* SPIF cleared by the write */
    uint8_t portb = a->data[PORTB_ADDR];
    spi_reply = 0xFF;
    if (!(portb & 0x01)) {                       /* MCP3208 */
        if (adc_idx == 0) {
            adc_first = v;
            spi_reply = 0;
        } else if (adc_idx == 1) {
            uint8_t ch = (uint8_t)(((adc_first & 1) << 2) | (v >> 6));
            adc_first = ch;
            spi_reply = (uint8_t)(mcp3208_code(ch) >> 8);
        } else if (adc_idx == 2) {
            spi_reply = (uint8_t)mcp3208_code(adc_first);
        }
        adc_idx++;
    } else if (!(portb & 0x10)) {                /* MCP4922 */
        if (dac_idx < 2)
            dac_bytes[dac_idx] = v;
        dac_idx++;
    }
    /* 8 SPI clocks: fosc / {4, 16, 64, 128}, halved by SPI2X */
    static const uint8_t div[4] = {4, 16, 64, 128};
    uint32_t d = div[a->data[SPCR_ADDR] & 3];
    if (a->data[SPSR_ADDR] & 1)
        d /= 2;
    avr_cycle_timer_register(a, 8 * d, spi_done, NULL);
}

static void portb_pin(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    int pin = (int)(intptr_t)param;
    if (pin == 0 && value)
        adc_idx = 0;
    if (pin == 4 && value) {            /* DAC CS rising: the word to its input register */
        if (dac_idx == 2) {
            uint16_t w = (uint16_t)(dac_bytes[0] << 8 | dac_bytes[1]);
            if (w & 0x1000)             /* SHDN high: active */
                dac_input[w >> 15] = w & 0x0FFF;
        }
        dac_idx = 0;
    }
    if (pin == 4 && !value)
        dac_idx = 0;
    if (pin == 5 && !value) {           /* LDAC falling: both outputs update */
        for (int i = 0; i < 2; i++) {
            st.dac_code[i] = dac_input[i];
            /* 5 V * code / 4096, then the op-amp stage trimmed to 10.00 V at 4095 */
            st.dac_volts[i] = 5.0 * dac_input[i] / 4096.0 * (2.0 * 4096.0 / 4095.0);
        }
        st.dac_updates++;
        if (cmd_done_cycle && avr->cycle >= cmd_done_cycle) {
            uint64_t d = avr->cycle - cmd_done_cycle;
            if (d < 2 * CYCLES_PER_MS) {
                st.cmd_delays++;
                st.cmd_delay_sum += d;
                if (d > st.cmd_delay_worst)
                    st.cmd_delay_worst = d;
            }
            cmd_done_cycle = 0;
        }
    }
}

/* ---- encoder and e-stop -------------------------------------------------------------------------- */
static int64_t enc_pos, enc_target;
static void drive_pins(void)
{
    static const uint8_t gray[4] = {3, 2, 0, 1};      /* count 0: A = B = high */
    uint8_t s = gray[enc_pos & 3];
    /* the levels we drive override the pins' pull-ups when the firmware writes PORTx (simavr
     * re-applies the pull-up on every PORT/DDR write unless the pin is declared external) */
    avr_ioport_external_t e = {.name = 'E', .mask = 0x30, .value = (uint8_t)(s << 4)};
    avr_ioctl(avr, AVR_IOCTL_IOPORT_SET_EXTERNAL('E'), &e);
    avr_ioport_external_t a = {.name = 'A', .mask = 0x01, .value = (uint8_t)(st.estop ? 1 : 0)};
    avr_ioctl(avr, AVR_IOCTL_IOPORT_SET_EXTERNAL('A'), &a);
    avr_raise_irq(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('E'), 4), s & 1);
    avr_raise_irq(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('E'), 5), (s >> 1) & 1);
    avr_raise_irq(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('A'), 0), st.estop ? 1 : 0);
}

/* After power-up and every reset: simavr 1.6 turns "strict" level triggering on for INT0-7 at
 * reset, i.e. a low INTn pin seen while ISC = 00 (the reset value) starts a poll that runs every
 * cycle and interrupts while the pin stays low, whatever ISC the firmware sets later (the
 * simulation crawls); the harness turns it off (a level interrupt then behaves as a falling edge,
 * which the firmware never uses). Its reset also zeroes the PIN registers: the lines we drive are
 * written back. */
static void after_reset(void)
{
    avr_extint_set_strict_lvl_trig(avr, 4, 0);
    avr_extint_set_strict_lvl_trig(avr, 5, 0);
    static const uint8_t gray[4] = {3, 2, 0, 1};
    uint8_t s = gray[enc_pos & 3];
    avr->data[0x2C] = (uint8_t)((avr->data[0x2C] & ~0x30) | (s << 4));     /* PINE */
    avr->data[0x20] = (uint8_t)((avr->data[0x20] & ~0x01) | (st.estop ? 1 : 0));  /* PINA */
    drive_pins();
}

static avr_cycle_count_t enc_step(avr_t *a, avr_cycle_count_t when, void *param)
{
    (void)a; (void)param;
    if (enc_pos == enc_target)
        return 0;
    enc_pos += enc_target > enc_pos ? 1 : -1;
    drive_pins();
    int64_t left = llabs(enc_target - enc_pos);
    if (!left)
        return 0;
    uint64_t gap = CYCLES_PER_MS / (uint64_t)(left + 1);
    return when + (gap < 64 ? 64 : gap);    /* 250 kHz edge rate at most */
}

/* ---- plant ------------------------------------------------------------------------------------- */
static int plant_in = -1, plant_out = -1;
static pid_t plant_pid;

static void plant_start(char **argv)
{
    int to[2], from[2];
    if (pipe(to) || pipe(from)) {
        perror("pipe");
        exit(2);
    }
    plant_pid = fork();
    if (plant_pid == 0) {
        dup2(to[0], 0);
        dup2(from[1], 1);
        close(to[1]);
        close(from[0]);
        execvp(argv[0], argv);
        perror("pam-board-sim: plant");
        _exit(127);
    }
    close(to[0]);
    close(from[1]);
    plant_in = to[1];
    plant_out = from[0];
}

static int read_full(int fd, void *buf, size_t n)
{
    uint8_t *p = buf;
    while (n) {
        ssize_t k = read(fd, p, n);
        if (k <= 0) {
            if (k < 0 && errno == EINTR)
                continue;
            return -1;
        }
        p += k;
        n -= (size_t)k;
    }
    return 0;
}

static int plant_read(void)
{
    struct { double v[4]; int64_t enc; } s;
    if (read_full(plant_out, &s, sizeof s))
        return -1;
    for (int i = 0; i < 4; i++)
        adc_volts[i] = s.v[i];
    enc_target = s.enc;
    return 0;
}

/* Pipelined by one millisecond: the valve voltages of ms k go to the plant at the end of ms k and
 * its sample comes back while the AVR simulates ms k + 1 (read at its end), so the two processes
 * run side by side instead of waking each other twice a millisecond; the ADC reads the plant one
 * millisecond later than pam-emulator's does (PLANT_LAG_MS, README.md). */
static int plant_pending;
static int plant_exchange(void)
{
    if (plant_pending && plant_read())
        return -1;
    double u[2] = {st.dac_volts[0], st.dac_volts[1]};
    if (write(plant_in, u, sizeof u) != (ssize_t)sizeof u)
        return -1;
    plant_pending = 1;
    return 0;
}

/* ---- status ------------------------------------------------------------------------------------ */
/* The busy cycles that fraction q of the tick periods do not exceed (the top of its 100-cycle
 * bin; the last bin holds every period of a whole tick or more). */
static uint64_t busy_quantile(double q)
{
    uint64_t seen = 0, need = (uint64_t)ceil(q * (double)st.ticks);
    for (unsigned i = 0; i <= CYCLES_PER_MS / 100; i++) {
        seen += st.busy_hist[i];
        if (seen >= need && seen)
            return i < CYCLES_PER_MS / 100 ? (i + 1) * 100ull : st.busy_worst;
    }
    return st.busy_worst;
}

static void status_json(FILE *f)
{
    double secs = st.ms / 1000.0;
    fprintf(f, "{\"ms\": %llu, \"tick_cycles_worst\": %llu, \"tick_cycles_mean\": %.1f, "
            "\"tick_cycles_p99\": %llu, \"tick_cycles_p999\": %llu, \"ticks\": %llu, "
            "\"ticks_over_half\": %llu, "
            "\"cycles_per_ms\": %u, \"tx_bytes\": %llu, \"rx_bytes\": %llu, "
            "\"tx_bytes_per_s\": %.1f, \"rx_bytes_per_s\": %.1f, \"line_bytes_per_s\": 100000, "
            "\"dropped_tx\": %llu, \"command_frames\": %llu, \"command_delays\": %llu, "
            "\"command_delay_worst_us\": %.2f, \"command_delay_mean_us\": %.2f, "
            "\"dac_updates\": %llu, \"dac_volts\": [%.4f, %.4f], \"dac_codes\": [%u, %u], "
            "\"late_ms\": %llu, \"worst_lag_us\": %llu, \"dropped_lag_ms\": %llu, "
            "\"resets\": %llu, \"estop\": %d, "
            "\"encoder\": %lld, \"encoder_target\": %lld, \"device\": \"%s\"}\n",
            (unsigned long long)st.ms, (unsigned long long)st.busy_worst,
            st.ticks ? (double)st.busy_total / st.ticks : 0.0,
            (unsigned long long)busy_quantile(0.99), (unsigned long long)busy_quantile(0.999),
            (unsigned long long)st.ticks, (unsigned long long)st.over_half, CYCLES_PER_MS,
            (unsigned long long)st.tx_bytes, (unsigned long long)st.rx_bytes,
            secs > 0 ? st.tx_bytes / secs : 0.0, secs > 0 ? st.rx_bytes / secs : 0.0,
            (unsigned long long)st.dropped_tx, (unsigned long long)st.cmd_frames,
            (unsigned long long)st.cmd_delays, st.cmd_delay_worst / 16.0,
            st.cmd_delays ? st.cmd_delay_sum / 16.0 / st.cmd_delays : 0.0,
            (unsigned long long)st.dac_updates, st.dac_volts[0], st.dac_volts[1],
            st.dac_code[0], st.dac_code[1], (unsigned long long)st.late_ms,
            (unsigned long long)st.worst_lag_us, (unsigned long long)st.dropped_lag_ms,
            (unsigned long long)st.resets, st.estop,
            (long long)enc_pos, (long long)enc_target, pty_path);
}

#define EEPROM_SIZE 4096
static void eeprom_io(const char *path, int save)
{
    static uint8_t image[EEPROM_SIZE], saved[EEPROM_SIZE];
    if (!path)
        return;
    avr_eeprom_desc_t d = {.ee = image, .offset = 0, .size = EEPROM_SIZE};
    if (!save) {
        FILE *f = fopen(path, "rb");
        if (!f)
            return;
        size_t n = fread(image, 1, EEPROM_SIZE, f);
        fclose(f);
        d.size = (uint32_t)n;
        avr_ioctl(avr, AVR_IOCTL_EEPROM_SET, &d);
        memcpy(saved, image, n);
        return;
    }
    avr_ioctl(avr, AVR_IOCTL_EEPROM_GET, &d);
    if (!memcmp(saved, image, EEPROM_SIZE))
        return;
    char tmp[512];
    snprintf(tmp, sizeof tmp, "%s.tmp%d", path, (int)getpid());
    FILE *f = fopen(tmp, "wb");
    if (!f)
        return;
    fwrite(image, 1, EEPROM_SIZE, f);
    fclose(f);
    rename(tmp, path);
    memcpy(saved, image, EEPROM_SIZE);
}

static void write_status(const char *path)
{
    if (!path)
        return;
    char tmp[512];
    snprintf(tmp, sizeof tmp, "%s.tmp%d", path, (int)getpid());
    FILE *f = fopen(tmp, "w");
    if (!f)
        return;
    status_json(f);
    fclose(f);
    rename(tmp, path);
}

static void control(void)
{
    static char line[256];
    static size_t len;
    char c;
    while (read(0, &c, 1) == 1) {
        if (c != '\n') {
            if (len < sizeof line - 1)
                line[len++] = c;
            continue;
        }
        line[len] = 0;
        len = 0;
        int v;
        if (sscanf(line, "estop %d", &v) == 1) {
            st.estop = v != 0;
            drive_pins();
        } else if (sscanf(line, "spi_stall %d", &v) == 1) {
            st.spi_stall_left = v;
        } else if (sscanf(line, "unplug %d", &v) == 1) {
            if (pty_master >= 0) {
                pty_close();
                unplug_until_ms = st.ms + (uint64_t)v;
                printf("pam-board-sim: unplugged\n");
            }
        } else if (!strcmp(line, "stats")) {
            status_json(stdout);
        }
        fflush(stdout);
    }
}

/* simavr's sleep callback usleeps to pace the simulation itself (we pace per millisecond): ours
 * only counts the cycles the core spends asleep */
static uint64_t slept;
static void sleep_cb(avr_t *a, avr_cycle_count_t how_long)
{
    (void)a;
    slept += 1 + how_long;
}

static void on_signal(int sig) { (void)sig; stop = 1; }


int main(int argc, char **argv)
{
    const char *elf = NULL, *status_path = NULL, *eeprom_path = NULL;
    double duration = 0;
    int i = 1;
    for (; i < argc && strcmp(argv[i], "--"); i++) {
        if (!strcmp(argv[i], "--link") && i + 1 < argc) link_path = argv[++i];
        else if (!strcmp(argv[i], "--status-file") && i + 1 < argc) status_path = argv[++i];
        else if (!strcmp(argv[i], "--duration") && i + 1 < argc) duration = atof(argv[++i]);
        else if (!strcmp(argv[i], "--eeprom") && i + 1 < argc) eeprom_path = argv[++i];
        else if (argv[i][0] != '-' && !elf) elf = argv[i];
        else { fprintf(stderr, "pam-board-sim: unknown argument %s\n", argv[i]); return 2; }
    }
    if (!elf || i >= argc - 1) {
        fprintf(stderr, "usage: pam-board-sim FIRMWARE.elf [--link PATH] [--status-file PATH] "
                "[--duration S] -- PLANT ARGV...\n");
        return 2;
    }
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    signal(SIGPIPE, SIG_IGN);
    fcntl(0, F_SETFL, fcntl(0, F_GETFL) | O_NONBLOCK);

    elf_firmware_t fw;
    memset(&fw, 0, sizeof fw);
    if (elf_read_firmware(elf, &fw)) {
        fprintf(stderr, "pam-board-sim: cannot read %s\n", elf);
        return 2;
    }
    avr = avr_make_mcu_by_name("atmega2560");
    if (!avr) {
        fprintf(stderr, "pam-board-sim: simavr has no atmega2560\n");
        return 2;
    }
    avr_init(avr);
    avr->frequency = F_CPU;
    avr->log = LOG_ERROR;
    avr_load_firmware(avr, &fw);
    avr->frequency = F_CPU;
    eeprom_io(eeprom_path, 0);
    avr->sleep = sleep_cb;

    uint32_t flags = 0;                 /* no console echo, no sleeping in status polls */
    avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
    flags &= ~(uint32_t)(AVR_UART_FLAG_STDIO | AVR_UART_FLAG_POLL_SLEEP);
    avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
                            uart_out, NULL);
    /* the SPI data register: ours, not simavr 1.6's fixed-100-us transfer */
    avr->io[AVR_DATA_TO_IO(SPDR_ADDR)].w.c = spdr_write;
    avr->io[AVR_DATA_TO_IO(SPDR_ADDR)].w.param = NULL;
    for (int pin = 0; pin <= 5; pin += 1)
        if (pin == 0 || pin == 4 || pin == 5)
            avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('B'), pin),
                                    portb_pin, (void *)(intptr_t)pin);
    frame_decoder_init(&host_frames);

    plant_start(argv + i + 1);
    if (plant_read()) {
        fprintf(stderr, "pam-board-sim: the plant did not start\n");
        return 2;
    }
    enc_pos = enc_target;
    after_reset();
    pty_open();

    uint32_t *profile = getenv("PAM_BOARD_SIM_PROFILE") ? calloc(1 << 17, 4) : NULL;
    static uint32_t pcs[65536];
    uint32_t n_pcs = 0;
    /* PAM_BOARD_SIM_PROFILE=FILE [PAM_BOARD_SIM_PROFILE_MIN=cycles]: the instructions of the tick
     * periods busier than MIN, per address (a developer's tool: avr-nm maps them) */
    uint64_t profile_min = getenv("PAM_BOARD_SIM_PROFILE_MIN") ?
        (uint64_t)atoll(getenv("PAM_BOARD_SIM_PROFILE_MIN")) : 0;
    uint64_t next_status = 0;
    wall_start = last_read_ns = now_ns();
    /* PAM_BOARD_SIM_TRACE: a line on stderr per tick period busier than PROFILE_MIN */
    int trace = getenv("PAM_BOARD_SIM_TRACE") != NULL;
    uint64_t rx0 = 0, tx0 = 0;
    uint64_t last_pc0 = 0, tick_c0 = 0, tick_slept0 = 0, tick_n = 0;
    int rc = 0;
    while (!stop) {
        uint64_t end = (st.ms + 1) * CYCLES_PER_MS;
        uint64_t next_slice = avr->cycle;
        while (avr->cycle < end) {
            if (profile && avr->state == cpu_Running && n_pcs < 65536)
                pcs[n_pcs++] = avr->pc;
            int state = avr_run(avr);
            if (state == cpu_Done || state == cpu_Crashed) {
                fprintf(stderr, "pam-board-sim: the AVR stopped (state %d)\n", state);
                stop = 1;
                rc = 1;
                break;
            }
            if (avr->pc == TICK_VECTOR && avr->cycle != tick_c0) {
                if (tick_c0 && ++tick_n > 100) {        /* after the start-up */
                    uint64_t busy = (avr->cycle - tick_c0) - (slept - tick_slept0);
                    st.ticks++;
                    st.busy_total += busy;
                    if (busy > st.busy_worst)
                        st.busy_worst = busy;
                    st.busy_hist[busy / 100 < CYCLES_PER_MS / 100 ? busy / 100 : CYCLES_PER_MS / 100]++;
                    st.over_half += busy > CYCLES_PER_MS / 2;
                    if (trace && busy > profile_min)    /* the period's own bytes each way */
                        fprintf(stderr, "tick %llu busy %llu rx %llu tx %llu\n",
                                (unsigned long long)tick_n, (unsigned long long)busy,
                                (unsigned long long)(st.rx_bytes - rx0),
                                (unsigned long long)(st.tx_bytes - tx0));
                    if (profile && busy > profile_min && busy < (getenv("PAM_BOARD_SIM_PROFILE_MAX") ? (uint64_t)atoll(getenv("PAM_BOARD_SIM_PROFILE_MAX")) : ~0ull))
                        for (uint32_t k = 0; k < n_pcs; k++)
                            profile[(pcs[k] >> 1) & 0x1FFFF]++;
                }
                n_pcs = 0;
                rx0 = st.rx_bytes;
                tx0 = st.tx_bytes;
                tick_c0 = avr->cycle;
                tick_slept0 = slept;
            }
            if (avr->pc == 0 && avr->cycle != last_pc0) {   /* a reset (the watchdog's) */
                last_pc0 = avr->cycle;
                st.resets++;
                after_reset();
            }
            if (in_pos < in_len)
                uart_feed();
            if (avr->cycle >= next_slice) {
                next_slice += CYCLES_PER_MS / 4;       /* the pty every 250 us */
                uart_read();
                uart_flush();
            }
        }
        st.ms++;
        if (st.spi_stall_left)
            st.spi_stall_left--;
        if (plant_exchange()) {
            fprintf(stderr, "pam-board-sim: the plant exited\n");
            rc = 1;
            break;
        }
        if (enc_pos != enc_target && !avr_cycle_timer_status(avr, enc_step, NULL))
            avr_cycle_timer_register(avr, 16, enc_step, NULL);
        uart_flush();
        control();
        if (unplug_until_ms && st.ms >= unplug_until_ms) {
            unplug_until_ms = 0;
            pty_open();
        }
        if (st.ms >= next_status) {
            next_status = st.ms + 100;
            write_status(status_path);
            eeprom_io(eeprom_path, 1);
        }
        if (duration > 0 && st.ms >= (uint64_t)(duration * 1000))
            break;
        /* pace to the wall clock */
        uint64_t due = wall_start + st.ms * 1000000ull, now = now_ns();
        if (now < due) {
            struct timespec t = {(time_t)(due / 1000000000ull), (long)(due % 1000000000ull)};
            clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &t, NULL);
        } else if (now - due > 2000000ull) {
            st.late_ms++;
            if ((now - due) / 1000 > st.worst_lag_us)
                st.worst_lag_us = (now - due) / 1000;
            /* a board never runs faster than its clock: beyond MAX_LAG behind (a starved
             * process), the lag is dropped rather than caught up in a burst of samples */
            if (now - due > MAX_LAG_NS) {
                st.dropped_lag_ms += (now - due) / 1000000ull;
                wall_start += now - due;
            }
        }
    }
    if (profile) {                      /* instructions executed per word address, for nm */
        FILE *f = fopen(getenv("PAM_BOARD_SIM_PROFILE"), "w");
        for (uint32_t a = 0; f && a < (1u << 17); a++)
            if (profile[a])
                fprintf(f, "%x %u\n", a * 2, profile[a]);
        if (f)
            fclose(f);
    }
    write_status(status_path);
    eeprom_io(eeprom_path, 1);
    printf("pam-board-sim: stopped after %llu ms: ", (unsigned long long)st.ms);
    status_json(stdout);
    fflush(stdout);
    if (pty_master >= 0)
        pty_close();
    close(plant_in);
    kill(plant_pid, SIGTERM);
    waitpid(plant_pid, NULL, 0);
    return rc;
}
