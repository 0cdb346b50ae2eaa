/* Generated from galileo_cnc/protocol/spec.py by
 *   python -m galileo_cnc.firmware_headers
 * Do not edit: change the Python definition and regenerate (docs/protocol.md). */
#ifndef GALILEO_PROTOCOL_H
#define GALILEO_PROTOCOL_H

#include <stdint.h>
#include <avr/pgmspace.h>

#define PROTO_VERSION 5
#define PROTO_FIRMWARE_VERSION "0.1.0"
#define PROTO_BANNER_NAME "galileo-cnc"
#define PROTO_MAX_LINE_BYTES 64 /* including the newline */
#define PROTO_RX_BUFFER_BYTES 128
#define PROTO_QUEUE_BLOCKS 8
#define PROTO_SEQ_MAX 65535UL
/* The check on every line, both ways: text, separator (even/odd text length),
 * CRC-16 over both as four upper-case hex digits. */
#define PROTO_CRC16_POLY 0x1021
#define PROTO_CRC16_INIT 0xFFFF
#define PROTO_CHECK_SEP_EVEN '*'
#define PROTO_CHECK_SEP_ODD '#'
#define PROTO_CHECK_BYTES 5

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
    ARG_INDEX,
};

#define ARG_COORD_LO (-9999999L)
#define ARG_COORD_HI (9999999L)
#define ARG_MS_LO (0L)
#define ARG_MS_HI (2000000L)
#define ARG_FEED_LO (0L)
#define ARG_FEED_HI (9999999L)
#define ARG_FLAG_LO (0L)
#define ARG_FLAG_HI (1L)
#define ARG_INDEX_LO (0L)
#define ARG_INDEX_HI (9999999L)

#define PROTO_MAX_ARGS 5

enum proto_command {
    CMD_RAPID,
    CMD_LINE,
    CMD_ARC_CW,
    CMD_ARC_CCW,
    CMD_LINE_X,
    CMD_ARC_CW_X,
    CMD_ARC_CCW_X,
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
    uint8_t kinds[5];
};

/* Tables: defined in the one file that defines PROTO_TABLES before including. */
extern const struct proto_command_spec proto_commands[CMD_COUNT] PROGMEM;
extern const char *const proto_error_texts[ERR_COUNT] PROGMEM;
extern const uint8_t proto_error_is_alarm[ERR_COUNT] PROGMEM;
extern const char *const proto_state_names[STATE_COUNT] PROGMEM;

#ifdef PROTO_TABLES

const struct proto_command_spec proto_commands[CMD_COUNT] PROGMEM = {
    {"R", 2, 2, 2, {ARG_COORD, ARG_COORD, 0, 0, 0}}, /* Rapid */
    {"L", 2, 3, 1, {ARG_COORD, ARG_COORD, ARG_COORD, 0, 0}}, /* LineTo */
    {"CW", 4, 4, 1, {ARG_COORD, ARG_COORD, ARG_COORD, ARG_COORD, 0}}, /* ArcTo */
    {"CCW", 4, 4, 1, {ARG_COORD, ARG_COORD, ARG_COORD, ARG_COORD, 0}}, /* ArcTo */
    {"LX", 3, 4, 1, {ARG_INDEX, ARG_COORD, ARG_COORD, ARG_COORD, 0}}, /* LineTo */
    {"CWX", 5, 5, 1, {ARG_INDEX, ARG_COORD, ARG_COORD, ARG_COORD, ARG_COORD}}, /* ArcTo */
    {"CCX", 5, 5, 1, {ARG_INDEX, ARG_COORD, ARG_COORD, ARG_COORD, ARG_COORD}}, /* ArcTo */
    {"PU", 0, 0, 1, {0, 0, 0, 0, 0}}, /* PenUp */
    {"PD", 0, 0, 1, {0, 0, 0, 0, 0}}, /* PenDown */
    {"FL", 0, 1, 3, {ARG_MS, 0, 0, 0, 0}}, /* Flash */
    {"DW", 1, 1, 1, {ARG_MS, 0, 0, 0, 0}}, /* Dwell */
    {"F", 1, 1, 0, {ARG_FEED, 0, 0, 0, 0}}, /* SetFeed */
    {"J", 3, 3, 1, {ARG_COORD, ARG_COORD, ARG_COORD, 0, 0}}, /* Jog */
    {"O", 0, 0, 1, {0, 0, 0, 0, 0}}, /* SetOrigin */
    {"H", 0, 0, 3, {0, 0, 0, 0, 0}}, /* Home */
    {"M", 1, 1, 0, {ARG_FLAG, 0, 0, 0, 0}}, /* Motors */
    {"E", 0, 0, 1, {0, 0, 0, 0, 0}}, /* EndJob */
    {"S", 0, 0, 0, {0, 0, 0, 0, 0}}, /* QueryStatus */
    {"V", 0, 0, 0, {0, 0, 0, 0, 0}}, /* QueryVersion */
    {"U", 0, 0, 0, {0, 0, 0, 0, 0}}, /* Unlock */
    {"C", 0, 0, 0, {0, 0, 0, 0, 0}}, /* QueryConfig */
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

#endif /* PROTO_TABLES */

#endif /* GALILEO_PROTOCOL_H */
