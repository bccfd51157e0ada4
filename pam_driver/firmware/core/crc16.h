/* CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF): the frame check of PROTOCOL.md. */
#ifndef PAM_CRC16_H
#define PAM_CRC16_H
#include <stdint.h>

#define CRC16_INIT 0xFFFFu

/* The byte-wise table split into its high and low bytes (256-byte aligned in flash on the AVR). */
extern const uint8_t crc16_table_high[256], crc16_table_low[256];
#ifdef __AVR__
#include <avr/pgmspace.h>
#define CRC16_TABLE(t, i) pgm_read_byte(&(t)[i])
#else
#define CRC16_TABLE(t, i) (t)[i]
#endif

/* One byte (inline: the receive path runs it for every byte): high = low ^ table_high[i],
 * low = table_low[i] with i = high ^ byte. */
static inline uint16_t crc16_update(uint16_t crc, uint8_t byte)
{
    uint8_t i = (uint8_t)((uint8_t)(crc >> 8) ^ byte);
    return (uint16_t)((uint16_t)(uint8_t)((uint8_t)crc ^ CRC16_TABLE(crc16_table_high, i)) << 8 |
                      CRC16_TABLE(crc16_table_low, i));
}
uint16_t crc16(const uint8_t *data, uint16_t n);

#endif
