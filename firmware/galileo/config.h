/* Machine configuration, generated from galileo_cnc/config/ (the defaults) by
 *   python -m galileo_cnc.firmware_headers [--config PROFILE.toml]
 * Edit the machine's profile and regenerate, then reflash: the banner's digest
 * tells the host which profile this build is for. docs/motion.md defines the
 * values. */
#ifndef GALILEO_CONFIG_H
#define GALILEO_CONFIG_H

#define CFG_F_CPU_HZ (16000000UL)            /* the board's clock */
#define CFG_TIMER1_PRESCALER (8)
#define CFG_TICKS_PER_S (2000000L)           /* Timer1 at F_CPU / 8: one tick is 0.5 us */
#define CFG_SERIAL_BAUD (115200UL)
#define CFG_FRAC_BITS (8)                    /* subtick = 1/256 tick */
#define CFG_RHO_BITS (15)                    /* path length per event in Q15 */
#define CFG_MIN_FEED_STEPS_PER_S (10)
#define CFG_MAX_ARC_COORD (32767)            /* |coordinate| relative to an arc centre */
#define CFG_STEPS_PER_REV (200)              /* mechanics (informational: the host converts) */
#define CFG_PITCH_NM (1250000L)
#define CFG_FEED_STEPS_PER_S (800)           /* default feed */
#define CFG_RAPID_STEPS_PER_S (1000)         /* pen-up travel */
#define CFG_Z_FEED_STEPS_PER_S (800)         /* pen up / down */
#define CFG_HOME_FEED_STEPS_PER_S (160)      /* homing seek and pull-off */
#define CFG_MAX_FEED_STEPS_PER_S (40000L)    /* = TICKS_PER_S / MIN_STEP_PERIOD */
#define CFG_MIN_STEP_PERIOD_TICKS (50)
#define CFG_ACCEL_STEPS_PER_S2 (40000L)      /* axis acceleration bound A */
#define CFG_RAMP_START_FACTOR (3)            /* a move starts at this x the period */
#define CFG_PEN_DOWN_Z_STEPS (0)
#define CFG_PEN_UP_Z_STEPS (300)
#define CFG_FLASH_DWELL_MS (200)
#define CFG_X_TRAVEL_MIN_STEPS (0)           /* soft limits, machine steps */
#define CFG_X_TRAVEL_MAX_STEPS (32000)
#define CFG_Y_TRAVEL_MIN_STEPS (0)
#define CFG_Y_TRAVEL_MAX_STEPS (32000)
#define CFG_Z_TRAVEL_MIN_STEPS (0)
#define CFG_Z_TRAVEL_MAX_STEPS (600)
#define CFG_X_STEP_PIN (11)                  /* Arduino pin numbers */
#define CFG_X_DIR_PIN (10)
#define CFG_Y_STEP_PIN (9)
#define CFG_Y_DIR_PIN (8)
#define CFG_Z_STEP_PIN (13)
#define CFG_Z_DIR_PIN (12)
#define CFG_X_HOME_PIN (7)                   /* -1: no end-stop; INPUT_PULLUP, active LOW */
#define CFG_Y_HOME_PIN (6)
#define CFG_Z_HOME_PIN (-1)
#define CFG_X_HOME_DIR (-1)                  /* seek direction */
#define CFG_Y_HOME_DIR (-1)
#define CFG_Z_HOME_DIR (1)
#define CFG_HOME_DEBOUNCE_READS (4)          /* consecutive active reads */
#define CFG_HOME_PULLOFF_STEPS (160)

#if defined(F_CPU) && F_CPU != CFG_F_CPU_HZ
#error "F_CPU differs from CFG_F_CPU_HZ: step timing and baud would be wrong"
#endif

/* The banner's `config` field and the `C` query's answer (docs/protocol.md). */
#define CFG_DIGEST "60d6fe2c"
#define CFG_VALUES_TEXT "STEPS_PER_REV=200 PITCH_NM=1250000 FEED_STEPS_PER_S=800 RAPID_STEPS_PER_S=1000 Z_FEED_STEPS_PER_S=800 HOME_FEED_STEPS_PER_S=160 MAX_FEED_STEPS_PER_S=40000 MIN_STEP_PERIOD_TICKS=50 ACCEL_STEPS_PER_S2=40000 RAMP_START_FACTOR=3 PEN_DOWN_Z_STEPS=0 PEN_UP_Z_STEPS=300 FLASH_DWELL_MS=200 X_TRAVEL_MIN_STEPS=0 X_TRAVEL_MAX_STEPS=32000 Y_TRAVEL_MIN_STEPS=0 Y_TRAVEL_MAX_STEPS=32000 Z_TRAVEL_MIN_STEPS=0 Z_TRAVEL_MAX_STEPS=600 X_STEP_PIN=11 X_DIR_PIN=10 Y_STEP_PIN=9 Y_DIR_PIN=8 Z_STEP_PIN=13 Z_DIR_PIN=12 X_HOME_PIN=7 Y_HOME_PIN=6 Z_HOME_PIN=-1 X_HOME_DIR=-1 Y_HOME_DIR=-1 Z_HOME_DIR=1 HOME_DEBOUNCE_READS=4 HOME_PULLOFF_STEPS=160"

#define CFG_N_BANDS 32
/* Arc timing bands (docs/motion.md §5.3): sin of the band edges, Q16, and
 * the mean path length per event inside each band, Q15. */
#define CFG_BAND_SIN_Q16 { \
    0, 9593, 13494, 16438, 18880, 20997, 22879, 24582, 26141, 27581, 28922, \
    30176, 31354, 32466, 33519, 34518, 35468, 36374, 37239, 38066, 38859, 39619, \
    40350, 41052, 41727, 42378, 43005, 43610, 44194, 44758, 45303, 45831 }
#define CFG_BAND_RHO_Q15 { \
    32886, 33294, 33661, 34029, 34401, 34776, 35155, 35538, 35926, 36317, 36713, \
    37112, 37517, 37925, 38338, 38756, 39178, 39605, 40036, 40472, 40913, 41358, \
    41809, 42264, 42724, 43190, 43660, 44135, 44616, 45102, 45593, 46090 }

#endif /* GALILEO_CONFIG_H */
