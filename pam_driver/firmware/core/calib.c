#include <string.h>

#include "calib.h"
#include "crc16.h"
#include "frame.h"

void calib_defaults(calib_t *c)
{
    memset(c, 0, sizeof *c);
    c->fitted = FITTED_ENCODER | FITTED_TORQUE | FITTED_SUPPLY;
    for (uint8_t i = 0; i < CALIB_CHANNELS; i++)
        c->gain_q14[i] = CALIB_GAIN_ONE;
    c->nominal_zero = 410;              /* 0.5 V * 4095 / 5 V */
    c->safe_code[0] = c->safe_code[1] = 0;      /* 0 V: vent (a 3/2 valve); see WIRING.md */
    c->cmd_min[0] = c->cmd_min[1] = 0;
    c->cmd_max[0] = c->cmd_max[1] = DAC_FULL_SCALE;
    c->p_max_counts = 3686;             /* 4.5 V: 1 MPa gauge, the transducer's top */
    c->p_max_samples = 5;
    calib_seal(c);
}

/* Layout on the wire and in EEPROM: the fields in order, little-endian. */
void calib_to_bytes(const calib_t *c, uint8_t *o)
{
    put_u16(o, c->magic); o[2] = c->version; o[3] = c->fitted; o += 4;
    for (uint8_t i = 0; i < CALIB_CHANNELS; i++, o += 2) put_u16(o, (uint16_t)c->zero_offset[i]);
    for (uint8_t i = 0; i < CALIB_CHANNELS; i++, o += 2) put_u16(o, c->gain_q14[i]);
    put_u16(o, c->nominal_zero); o += 2;
    for (uint8_t i = 0; i < 2; i++, o += 2) put_u16(o, c->safe_code[i]);
    for (uint8_t i = 0; i < 2; i++, o += 2) put_u16(o, c->cmd_min[i]);
    for (uint8_t i = 0; i < 2; i++, o += 2) put_u16(o, c->cmd_max[i]);
    put_u16(o, c->p_max_counts); o += 2;
    o[0] = c->p_max_samples; o[1] = c->reserved; o += 2;
    put_u16(o, c->crc);
}

void calib_from_bytes(calib_t *c, const uint8_t *i)
{
    c->magic = get_u16(i); c->version = i[2]; c->fitted = i[3]; i += 4;
    for (uint8_t k = 0; k < CALIB_CHANNELS; k++, i += 2) c->zero_offset[k] = (int16_t)get_u16(i);
    for (uint8_t k = 0; k < CALIB_CHANNELS; k++, i += 2) c->gain_q14[k] = get_u16(i);
    c->nominal_zero = get_u16(i); i += 2;
    for (uint8_t k = 0; k < 2; k++, i += 2) c->safe_code[k] = get_u16(i);
    for (uint8_t k = 0; k < 2; k++, i += 2) c->cmd_min[k] = get_u16(i);
    for (uint8_t k = 0; k < 2; k++, i += 2) c->cmd_max[k] = get_u16(i);
    c->p_max_counts = get_u16(i); i += 2;
    c->p_max_samples = i[0]; c->reserved = i[1]; i += 2;
    c->crc = get_u16(i);
}

static uint16_t checksum(const calib_t *c)
{
    uint8_t bytes[CALIB_SIZE];
    calib_to_bytes(c, bytes);
    return crc16(bytes, (uint16_t)(CALIB_SIZE - 2));
}

void calib_seal(calib_t *c)
{
    c->magic = CALIB_MAGIC;
    c->version = CALIB_VERSION;
    c->crc = checksum(c);
}

uint8_t calib_valid(const calib_t *c)
{
    if (c->magic != CALIB_MAGIC || c->version != CALIB_VERSION || c->crc != checksum(c))
        return 0;
    if (c->fitted & ~(FITTED_ENCODER | FITTED_TORQUE | FITTED_SUPPLY))
        return 0;
    for (uint8_t i = 0; i < CALIB_CHANNELS; i++) {
        if (c->zero_offset[i] > CALIB_ZERO_RANGE || c->zero_offset[i] < -CALIB_ZERO_RANGE)
            return 0;
        if (c->gain_q14[i] < CALIB_GAIN_ONE / 2 || c->gain_q14[i] > CALIB_GAIN_ONE * 2)
            return 0;
    }
    if (c->nominal_zero > ADC_FULL_SCALE || c->p_max_counts > ADC_FULL_SCALE || !c->p_max_samples)
        return 0;
    for (uint8_t i = 0; i < 2; i++) {
        if (c->cmd_min[i] > c->cmd_max[i] || c->cmd_max[i] > DAC_FULL_SCALE)
            return 0;
        if (c->safe_code[i] > DAC_FULL_SCALE)
            return 0;
    }
    return 1;
}

uint16_t calib_pressure(const calib_t *c, uint8_t ch, uint16_t raw)
{
    /* |raw - offset - zero| < 2^15 and gain < 2^16: a 16 x 16 -> 32 bit product (the AVR's
     * hardware multiplier, not a 32-bit software one) */
    int16_t d = (int16_t)((int16_t)raw - c->zero_offset[ch] - (int16_t)c->nominal_zero);
    int32_t prod = ((int32_t)d * c->gain_q14[ch]) * 4;      /* >> 14 as << 2, >> 16 */
    int32_t v = (int32_t)c->nominal_zero + (int16_t)(prod >> 16);
    if (v < 0)
        return 0;
    return v > (int32_t)ADC_FULL_SCALE ? ADC_FULL_SCALE : (uint16_t)v;
}
