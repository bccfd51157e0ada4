/* The board's calibration, stored in EEPROM with a CRC-16: pressure sensor zero and gain, the safe
 * output per valve channel, the command and pressure limits and what is fitted. Plain data, no
 * hardware access: the HAL reads and writes the bytes. */
#ifndef PAM_CALIB_H
#define PAM_CALIB_H
#include <stdint.h>

#define CALIB_MAGIC 0x4350u             /* "PC" */
#define CALIB_VERSION 1u
#define CALIB_CHANNELS 3u               /* pressure P1, P2, P_supply */
#define CALIB_GAIN_ONE 16384u           /* gain_q14: 1.0 */
#define CALIB_ZERO_RANGE 200            /* auto-zero: |offset| <= this many counts */
#define ADC_FULL_SCALE 4095u
#define DAC_FULL_SCALE 4095u

#define FITTED_ENCODER 0x01u            /* = the HELLO_ACK flags of PROTOCOL.md */
#define FITTED_TORQUE 0x02u
#define FITTED_SUPPLY 0x04u

typedef struct {
    uint16_t magic;
    uint8_t version;
    uint8_t fitted;                     /* FITTED_* */
    int16_t zero_offset[CALIB_CHANNELS];/* ADC counts subtracted from the raw reading */
    uint16_t gain_q14[CALIB_CHANNELS];  /* scale around nominal_zero, 16384 = 1 */
    uint16_t nominal_zero;              /* ADC counts of 0 Pa gauge (0.5 V of 5 V: 410) */
    uint16_t safe_code[2];              /* DAC counts applied in every safe state */
    uint16_t cmd_min[2], cmd_max[2];    /* COMMAND codes are clipped to [min, max] */
    uint16_t p_max_counts;              /* P1 or P2 above this (corrected counts) -> fault */
    uint8_t p_max_samples;              /* ... for this many samples in a row */
    uint8_t reserved;
    uint16_t crc;                       /* CRC-16 of every byte before it */
} calib_t;

#define CALIB_SIZE 36u                  /* bytes on the wire and in EEPROM */

void calib_defaults(calib_t *c);
void calib_seal(calib_t *c);            /* sets magic, version and crc */
/* 1 if magic, version, crc and every field are valid. */
uint8_t calib_valid(const calib_t *c);
/* Raw ADC counts of pressure channel ch -> corrected counts (0..ADC_FULL_SCALE). */
uint16_t calib_pressure(const calib_t *c, uint8_t ch, uint16_t raw);
/* Clips a DAC code of valve channel ch to [cmd_min, cmd_max]; *clipped set when it did. */
static inline uint16_t calib_command(const calib_t *c, uint8_t ch, uint16_t code,
                                     uint8_t *clipped)
{
    if (code < c->cmd_min[ch]) { *clipped = 1; return c->cmd_min[ch]; }
    if (code > c->cmd_max[ch]) { *clipped = 1; return c->cmd_max[ch]; }
    return code;
}
/* Serialisation (little-endian, CALIB_SIZE bytes) for the CAL frames and the EEPROM. */
void calib_to_bytes(const calib_t *c, uint8_t *out);
void calib_from_bytes(calib_t *c, const uint8_t *in);

#endif
