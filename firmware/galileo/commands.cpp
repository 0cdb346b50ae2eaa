/* Command lines (docs/protocol.md): checksum, sequence, mnemonic, arguments, one
 * reply per line; the supervisor for alarms, aborts, overruns and status. */
#include <avr/pgmspace.h>
#include <string.h>
#include <util/crc16.h>

#define PROTO_TABLES
#include "commands.h"
#include "planner.h"
#include "protocol.h"
#include "serial.h"
#include "stepper.h"

#if PROTO_CRC16_POLY != 0x1021 || PROTO_CRC16_INIT != 0xFFFF
#error "the line check is avr-libc's _crc_xmodem_update started at 0xFFFF (CRC-16/CCITT-FALSE)"
#endif

/* `make -C firmware PROFILE=1`: Uno pin A1 is high while the main loop handles
 * one command line (checks, parse, plan, reply queued), A2 while the planner
 * runs (bench/bench_firmware.py measures both in simavr's pin trace). */
#ifdef GALILEO_PROFILE
#define LINE_PROFILE_BEGIN() (PORTC |= _BV(1))
#define LINE_PROFILE_END() (PORTC &= ~_BV(1))
#define PLAN_PROFILE_BEGIN() (PORTC |= _BV(2))
#define PLAN_PROFILE_END() (PORTC &= ~_BV(2))
#else
#define LINE_PROFILE_BEGIN()
#define LINE_PROFILE_END()
#define PLAN_PROFILE_BEGIN()
#define PLAN_PROFILE_END()
#endif

static uint16_t expected_seq = 1;
static uint16_t last_seq;
static uint8_t alarm_code; /* nonzero: locked until Unlock */
static uint16_t reported_overruns;

static struct {
    uint8_t waiting, cmd, nargs;
    uint16_t seq;
    int32_t args[PROTO_MAX_ARGS];
} pending;

static const char AXIS_NAMES[3] = {'X', 'Y', 'Z'};

/* `error:CODE [N<seq> ]text`, or `alarm:` / `msg:` for what the machine reports
 * on its own (alarms lock it, messages do not). */
static void print_error_head(uint8_t code, uint8_t with_seq, uint16_t seq, uint8_t async)
{
    if (async)
        serial_print_P(pgm_read_byte(&proto_error_is_alarm[code]) ? PSTR("alarm:") : PSTR("msg:"));
    else
        serial_print_P(PSTR("error:"));
    serial_print_int(code);
    if (with_seq) {
        serial_print_P(PSTR(" N"));
        serial_print_int(seq);
    }
    serial_write(' ');
    serial_print_P((const char *)pgm_read_word(&proto_error_texts[code]));
}

static void reply_error(uint8_t code, uint8_t with_seq, uint16_t seq)
{
    print_error_head(code, with_seq, seq, 0);
    if (code == ERR_SOFT_LIMIT) {
        serial_print_P(PSTR(": "));
        serial_write(AXIS_NAMES[pl_violation.axis]);
        serial_print_P(PSTR(" would reach "));
        serial_print_int(pl_violation.value);
        serial_print_P(pl_violation.above ? PSTR(", above ") : PSTR(", below "));
        serial_print_int(pl_violation.limit);
    }
    serial_end_line();
}

static void reply_resend(void)
{
    serial_print_P(PSTR("rs N"));
    serial_print_int(expected_seq);
    serial_end_line();
}

static void print_banner(void)
{
    serial_print_P(PSTR(PROTO_BANNER_NAME " " PROTO_FIRMWARE_VERSION " proto "));
    serial_print_int(PROTO_VERSION);
    serial_print_P(PSTR(" rx "));
    serial_print_int(PROTO_RX_BUFFER_BYTES);
    serial_print_P(PSTR(" queue "));
    serial_print_int(PROTO_QUEUE_BLOCKS);
    serial_print_P(PSTR(" config " CFG_DIGEST));
}

static uint8_t machine_state(void)
{
    if (alarm_code || st_phase == PHASE_ALARM)
        return STATE_ALARM;
    if (st_hold_request || st_phase == PHASE_HELD)
        return STATE_HOLD;
    if (stepper_homing())
        return STATE_HOMING;
    if (st_phase != PHASE_IDLE || queue_depth())
        return STATE_RUN;
    return STATE_IDLE;
}

static void print_status(void)
{
    /* The state before the position: a report that says idle then holds the final
     * position. Read the other way round, the last step's interrupt could land
     * between the two reads (idle, one step short: seen once in CI). */
    uint8_t state = machine_state();
    int32_t pos[3], origin[3];
    stepper_position(pos, origin);
    serial_print_P(PSTR("status:"));
    serial_print_P((const char *)pgm_read_word(&proto_state_names[state]));
    for (uint8_t a = 0; a < 3; a++) {
        serial_write(' ');
        serial_write(AXIS_NAMES[a]);
        serial_print_int(pos[a] - origin[a]);
    }
    serial_print_P(PSTR(" Q"));
    serial_print_int(queue_depth());
    serial_print_P(PSTR(" N"));
    serial_print_int(last_seq);
}

void commands_banner(void)
{
    print_banner();
    serial_end_line();
}

static uint8_t hex_value(char c)
{
    if (c >= '0' && c <= '9')
        return c - '0';
    if (c >= 'A' && c <= 'F')
        return c - 'A' + 10;
    return 0xFF;
}

/* Signed decimal of at most 9 digits; returns the first character after it. */
static const char *parse_int(const char *p, int32_t *out)
{
    uint8_t neg = *p == '-', digits = 0;
    if (neg)
        p++;
    int32_t v = 0;
    while (*p >= '0' && *p <= '9' && digits < 10) {
        v = v * 10 + (*p++ - '0');
        digits++;
    }
    if (digits == 0 || digits > 9)
        return 0;
    *out = neg ? -v : v;
    return p;
}

static void handle_line(char *s, uint8_t len)
{
    /* The check: the separator's parity catches every lost or doubled byte, the
     * CRC-16 (over text and separator) every error of up to three bits. */
    if (len <= PROTO_CHECK_BYTES) {
        reply_resend();
        return;
    }
    uint8_t text_len = len - PROTO_CHECK_BYTES;
    uint8_t bad = s[text_len] != (text_len & 1 ? PROTO_CHECK_SEP_ODD : PROTO_CHECK_SEP_EVEN);
    uint16_t crc = PROTO_CRC16_INIT, check = 0;
    for (uint8_t i = 0; i <= text_len; i++)
        crc = _crc_xmodem_update(crc, (uint8_t)s[i]);
    for (uint8_t i = text_len + 1; i < len; i++) {
        uint8_t v = hex_value(s[i]);
        bad |= v > 15;
        check = check << 4 | (v & 0xF);
    }
    if (bad || crc != check) {
        reply_resend();
        return;
    }
    s[text_len] = 0;
    const char *p = s + 1;
    uint32_t seq = 0;
    uint8_t digits = 0;
    while (*p >= '0' && *p <= '9' && digits < 6) {
        seq = seq * 10 + (*p++ - '0');
        digits++;
    }
    if (s[0] != 'N' || digits == 0 || digits > 5 || seq > PROTO_SEQ_MAX || *p != ' ') {
        reply_error(ERR_BAD_LINE, 0, 0);
        return;
    }
    if (seq != 0 && seq != expected_seq) {
        reply_resend();
        return;
    }
    /* The number counts only once the line is accepted (execute_pending): a refused
     * line is expected again, so the lines sent behind it draw `rs` and never run, and
     * status N shows the refusal to a host whose error reply was lost. */
    uint16_t line_seq = (uint16_t)seq;
    p++;
    char mnemonic[4];
    uint8_t n = 0;
    while (*p >= 'A' && *p <= 'Z' && n < 3)
        mnemonic[n++] = *p++;
    mnemonic[n] = 0;
    uint8_t cmd;
    for (cmd = 0; cmd < CMD_COUNT; cmd++)
        if (n && !strcmp_P(mnemonic, proto_commands[cmd].mnemonic))
            break;
    if (cmd == CMD_COUNT || (*p != ' ' && *p != 0)) {
        reply_error(ERR_UNKNOWN_COMMAND, 1, line_seq);
        return;
    }
    uint8_t nargs = 0, max_args = pgm_read_byte(&proto_commands[cmd].max_args);
    while (*p == ' ' && nargs < max_args) {
        p = parse_int(p + 1, &pending.args[nargs]);
        if (!p)
            break;
        /* In flash: RAM is the scarce one. */
        static const int32_t lo_of[] PROGMEM = {ARG_COORD_LO, ARG_MS_LO, ARG_FEED_LO,
                                                ARG_FLAG_LO, ARG_INDEX_LO};
        static const int32_t hi_of[] PROGMEM = {ARG_COORD_HI, ARG_MS_HI, ARG_FEED_HI,
                                                ARG_FLAG_HI, ARG_INDEX_HI};
        uint8_t kind = pgm_read_byte(&proto_commands[cmd].kinds[nargs]);
        if (pending.args[nargs] < (int32_t)pgm_read_dword(&lo_of[kind])
            || pending.args[nargs] > (int32_t)pgm_read_dword(&hi_of[kind])) {
            p = 0;
            break;
        }
        nargs++;
    }
    if (!p || *p != 0 || nargs < pgm_read_byte(&proto_commands[cmd].min_args)) {
        reply_error(ERR_BAD_ARGUMENT, 1, line_seq);
        return;
    }
    pending.cmd = cmd;
    pending.nargs = nargs;
    pending.seq = line_seq;
    pending.waiting = 1;
}

/* Run the pending command once the queue has room; exactly one reply. */
static void execute_pending(void)
{
    uint8_t cmd = pending.cmd, err = 0;
    uint8_t protocol_only = cmd == CMD_STATUS || cmd == CMD_VERSION || cmd == CMD_UNLOCK
                            || cmd == CMD_CONFIG;
    if (!protocol_only && alarm_code)
        err = ERR_LOCKED;
    else if (!protocol_only && pl.ended)
        err = ERR_JOB_ENDED;
    if (!err) {
        if (queue_free() < planner_blocks_needed(cmd))
            return; /* wait: the line stays unanswered, the host keeps counting */
        if (cmd == CMD_UNLOCK) {
            alarm_code = 0;
            pl.ended = 0;
        } else if (!protocol_only) {
            PLAN_PROFILE_BEGIN();
            err = planner_execute(cmd, pending.args, pending.nargs);
            PLAN_PROFILE_END();
        }
    }
    pending.waiting = 0;
    if (err) {
        reply_error(err, 1, pending.seq);
        return;
    }
    last_seq = pending.seq;
    expected_seq = last_seq >= PROTO_SEQ_MAX ? 1 : last_seq + 1;
    serial_print_P(PSTR("ok N"));
    serial_print_int(pending.seq);
    if (cmd == CMD_STATUS) {
        serial_write(' ');
        print_status();
    } else if (cmd == CMD_VERSION) {
        serial_write(' ');
        print_banner();
    } else if (cmd == CMD_CONFIG) {
        serial_print_P(PSTR(" config " CFG_VALUES_TEXT));
    }
    serial_end_line();
}

static void enter_alarm(uint8_t code)
{
    alarm_code = code;
    planner_resync();
    print_error_head(code, 0, 0, 1);
    serial_end_line();
}

void commands_service(void)
{
    serial_service();
    if (serial_status_request) {
        serial_status_request = 0;
        print_status();
        serial_end_line();
    }
    if (st_phase == PHASE_ALARM && stepper_flush())
        enter_alarm(st_alarm_code);
    if (st_abort_request && stepper_flush()) {
        st_abort_request = 0;
        st_hold_request = 0;
        enter_alarm(ERR_ABORTED);
    }
    if (st_overruns != reported_overruns) {
        reported_overruns = st_overruns;
        print_error_head(ERR_STEP_OVERRUN, 0, 0, 1);
        serial_end_line();
    }
    stepper_service();
    if (!pending.waiting) {
        char *line;
        uint8_t len;
        uint8_t got = serial_read_line(&line, &len);
        if (got == LINE_TOO_LONG)
            reply_error(ERR_LINE_TOO_LONG, 0, 0);
        else if (got == LINE_READY) {
            LINE_PROFILE_BEGIN();
            handle_line(line, len);
        }
    }
    if (pending.waiting)
        execute_pending();
    LINE_PROFILE_END();
}
