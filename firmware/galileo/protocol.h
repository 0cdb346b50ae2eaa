/* Generated from galileo_cnc/protocol/spec.py by
 *   python -m galileo_cnc.firmware_headers
 * Do not edit: change the Python definition and regenerate (docs/protocol.md). */
#ifndef GALILEO_PROTOCOL_H
#define GALILEO_PROTOCOL_H

#include <stdint.h>
#include <avr/pgmspace.h>

#define PROTO_VERSION 3
#define PROTO_FIRMWARE_VERSION "0.1.0"
#define PROTO_BANNER_NAME "galileo-cnc"
#define PROTO_MAX_LINE_BYTES 64 /* including the newline */
#define PROTO_RX_BUFFER_BYTES 128
#define PROTO_QUEUE_BLOCKS 8
#define PROTO_SEQ_MAX 65535UL
#define PROTO_CRC8_POLY 0x07

/* Real-time bytes, picked off in the receive interrupt. */
#define PROTO_RT_STATUS 0x83
#define PROTO_RT_HOLD 0x8C
#define PROTO_RT_RESUME 0x95
#define PROTO_RT_ABORT 0x9A

enum proto_arg_kind {
    ARG_COORD,
    ARG_MS,
    ARG_FEED,
    ARG_FLAG,
};

#define ARG_COORD_LO (-9999999L)
#define ARG_COORD_HI (9999999L)
#define ARG_MS_LO (0L)
#define ARG_MS_HI (2000000L)
#define ARG_FEED_LO (0L)
#define ARG_FEED_HI (9999999L)
#define ARG_FLAG_LO (0L)
#define ARG_FLAG_HI (1L)

#define PROTO_MAX_ARGS 4

enum proto_command {
    CMD_RAPID,
    CMD_LINE,
    CMD_ARC_CW,
    CMD_ARC_CCW,
    CMD_PEN_UP,
    CMD_PEN_DOWN,
    CMD_FLASH,
    CMD_DWELL,
    CMD_FEED,
    CMD_JOG,
    CMD_ORIGIN,
    CMD_HOME,
    CMD_MOTORS,
    CMD_END_JOB,
    CMD_STATUS,
    CMD_VERSION,
    CMD_UNLOCK,
    CMD_CONFIG,
    CMD_COUNT
};

enum proto_error {
    ERR_BAD_LINE = 1,
    ERR_LINE_TOO_LONG = 2,
    ERR_UNKNOWN_COMMAND = 3,
    ERR_BAD_ARGUMENT = 4,
    ERR_SOFT_LIMIT = 5,
    ERR_FEED_RANGE = 6,
    ERR_ARC_TOO_LARGE = 7,
    ERR_JOB_ENDED = 8,
    ERR_LOCKED = 9,
    ERR_HOME_SWITCH_ACTIVE = 10,
    ERR_HOME_NOT_FOUND = 11,
    ERR_HOME_PULLOFF = 12,
    ERR_STEP_OVERRUN = 13,
    ERR_ABORTED = 14,
    ERR_COUNT = 15
};

enum proto_state {
    STATE_IDLE,
    STATE_RUN,
    STATE_HOLD,
    STATE_ALARM,
    STATE_HOMING,
    STATE_COUNT
};

struct proto_command_spec {
    char mnemonic[4];
    uint8_t min_args, max_args;
    uint8_t blocks; /* queue room reserved before planning (HOME: per axis) */
    uint8_t kinds[4];
};

/* Tables: defined in the one file that defines PROTO_TABLES before including. */
extern const struct proto_command_spec proto_commands[CMD_COUNT] PROGMEM;
extern const char *const proto_error_texts[ERR_COUNT] PROGMEM;
extern const uint8_t proto_error_is_alarm[ERR_COUNT] PROGMEM;
extern const char *const proto_state_names[STATE_COUNT] PROGMEM;
extern const uint8_t proto_crc8_table[256] PROGMEM;

#ifdef PROTO_TABLES

const struct proto_command_spec proto_commands[CMD_COUNT] PROGMEM = {
    {"R", 2, 2, 2, {ARG_COORD, ARG_COORD, 0, 0}}, /* Rapid */
    {"L", 2, 3, 1, {ARG_COORD, ARG_COORD, ARG_COORD, 0}}, /* LineTo */
    {"CW", 4, 4, 1, {ARG_COORD, ARG_COORD, ARG_COORD, ARG_COORD}}, /* ArcTo */
    {"CCW", 4, 4, 1, {ARG_COORD, ARG_COORD, ARG_COORD, ARG_COORD}}, /* ArcTo */
    {"PU", 0, 0, 1, {0, 0, 0, 0}}, /* PenUp */
    {"PD", 0, 0, 1, {0, 0, 0, 0}}, /* PenDown */
    {"FL", 0, 1, 3, {ARG_MS, 0, 0, 0}}, /* Flash */
    {"DW", 1, 1, 1, {ARG_MS, 0, 0, 0}}, /* Dwell */
    {"F", 1, 1, 0, {ARG_FEED, 0, 0, 0}}, /* SetFeed */
    {"J", 3, 3, 1, {ARG_COORD, ARG_COORD, ARG_COORD, 0}}, /* Jog */
    {"O", 0, 0, 1, {0, 0, 0, 0}}, /* SetOrigin */
    {"H", 0, 0, 3, {0, 0, 0, 0}}, /* Home */
    {"M", 1, 1, 0, {ARG_FLAG, 0, 0, 0}}, /* Motors */
    {"E", 0, 0, 1, {0, 0, 0, 0}}, /* EndJob */
    {"S", 0, 0, 0, {0, 0, 0, 0}}, /* QueryStatus */
    {"V", 0, 0, 0, {0, 0, 0, 0}}, /* QueryVersion */
    {"U", 0, 0, 0, {0, 0, 0, 0}}, /* Unlock */
    {"C", 0, 0, 0, {0, 0, 0, 0}}, /* QueryConfig */
};

static const char proto_error_text_1[] PROGMEM = "malformed line";
static const char proto_error_text_2[] PROGMEM = "line too long";
static const char proto_error_text_3[] PROGMEM = "unknown command";
static const char proto_error_text_4[] PROGMEM = "bad argument";
static const char proto_error_text_5[] PROGMEM = "soft limit";
static const char proto_error_text_6[] PROGMEM = "feed out of range";
static const char proto_error_text_7[] PROGMEM = "arc radius too large";
static const char proto_error_text_8[] PROGMEM = "job has ended, send U";
static const char proto_error_text_9[] PROGMEM = "alarm, send U";
static const char proto_error_text_10[] PROGMEM = "end-stop already active, jog away";
static const char proto_error_text_11[] PROGMEM = "end-stop not found";
static const char proto_error_text_12[] PROGMEM = "end-stop still active after pull-off";
static const char proto_error_text_13[] PROGMEM = "step interrupt overrun, timing slipped";
static const char proto_error_text_14[] PROGMEM = "aborted";
const char *const proto_error_texts[ERR_COUNT] PROGMEM = {
    0, proto_error_text_1, proto_error_text_2, proto_error_text_3,
    proto_error_text_4, proto_error_text_5, proto_error_text_6, proto_error_text_7,
    proto_error_text_8, proto_error_text_9, proto_error_text_10, proto_error_text_11,
    proto_error_text_12, proto_error_text_13, proto_error_text_14
};
const uint8_t proto_error_is_alarm[ERR_COUNT] PROGMEM = {
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 0, 1
};

static const char proto_state_idle[] PROGMEM = "idle";
static const char proto_state_run[] PROGMEM = "run";
static const char proto_state_hold[] PROGMEM = "hold";
static const char proto_state_alarm[] PROGMEM = "alarm";
static const char proto_state_homing[] PROGMEM = "homing";
const char *const proto_state_names[STATE_COUNT] PROGMEM = {
    proto_state_idle, proto_state_run, proto_state_hold, proto_state_alarm, proto_state_homing
};

const uint8_t proto_crc8_table[256] PROGMEM = {
    0x00, 0x07, 0x0E, 0x09, 0x1C, 0x1B, 0x12, 0x15, 0x38, 0x3F, 0x36, 0x31,
    0x24, 0x23, 0x2A, 0x2D, 0x70, 0x77, 0x7E, 0x79, 0x6C, 0x6B, 0x62, 0x65,
    0x48, 0x4F, 0x46, 0x41, 0x54, 0x53, 0x5A, 0x5D, 0xE0, 0xE7, 0xEE, 0xE9,
    0xFC, 0xFB, 0xF2, 0xF5, 0xD8, 0xDF, 0xD6, 0xD1, 0xC4, 0xC3, 0xCA, 0xCD,
    0x90, 0x97, 0x9E, 0x99, 0x8C, 0x8B, 0x82, 0x85, 0xA8, 0xAF, 0xA6, 0xA1,
    0xB4, 0xB3, 0xBA, 0xBD, 0xC7, 0xC0, 0xC9, 0xCE, 0xDB, 0xDC, 0xD5, 0xD2,
    0xFF, 0xF8, 0xF1, 0xF6, 0xE3, 0xE4, 0xED, 0xEA, 0xB7, 0xB0, 0xB9, 0xBE,
    0xAB, 0xAC, 0xA5, 0xA2, 0x8F, 0x88, 0x81, 0x86, 0x93, 0x94, 0x9D, 0x9A,
    0x27, 0x20, 0x29, 0x2E, 0x3B, 0x3C, 0x35, 0x32, 0x1F, 0x18, 0x11, 0x16,
    0x03, 0x04, 0x0D, 0x0A, 0x57, 0x50, 0x59, 0x5E, 0x4B, 0x4C, 0x45, 0x42,
    0x6F, 0x68, 0x61, 0x66, 0x73, 0x74, 0x7D, 0x7A, 0x89, 0x8E, 0x87, 0x80,
    0x95, 0x92, 0x9B, 0x9C, 0xB1, 0xB6, 0xBF, 0xB8, 0xAD, 0xAA, 0xA3, 0xA4,
    0xF9, 0xFE, 0xF7, 0xF0, 0xE5, 0xE2, 0xEB, 0xEC, 0xC1, 0xC6, 0xCF, 0xC8,
    0xDD, 0xDA, 0xD3, 0xD4, 0x69, 0x6E, 0x67, 0x60, 0x75, 0x72, 0x7B, 0x7C,
    0x51, 0x56, 0x5F, 0x58, 0x4D, 0x4A, 0x43, 0x44, 0x19, 0x1E, 0x17, 0x10,
    0x05, 0x02, 0x0B, 0x0C, 0x21, 0x26, 0x2F, 0x28, 0x3D, 0x3A, 0x33, 0x34,
    0x4E, 0x49, 0x40, 0x47, 0x52, 0x55, 0x5C, 0x5B, 0x76, 0x71, 0x78, 0x7F,
    0x6A, 0x6D, 0x64, 0x63, 0x3E, 0x39, 0x30, 0x37, 0x22, 0x25, 0x2C, 0x2B,
    0x06, 0x01, 0x08, 0x0F, 0x1A, 0x1D, 0x14, 0x13, 0xAE, 0xA9, 0xA0, 0xA7,
    0xB2, 0xB5, 0xBC, 0xBB, 0x96, 0x91, 0x98, 0x9F, 0x8A, 0x8D, 0x84, 0x83,
    0xDE, 0xD9, 0xD0, 0xD7, 0xC2, 0xC5, 0xCC, 0xCB, 0xE6, 0xE1, 0xE8, 0xEF,
    0xFA, 0xFD, 0xF4, 0xF3
};

#endif /* PROTO_TABLES */

#endif /* GALILEO_PROTOCOL_H */
