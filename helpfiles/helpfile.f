galileo-cnc console
===================

Type a command at the >> prompt and press Enter. Tab completes command names
and file names; Up/Down recall earlier commands (kept between runs). The bar at
the bottom shows the port, the machine's state and the head position in mm.
Ctrl-C at the prompt gives a new prompt; Ctrl-C or q during a job stops it (the
machine ramps down first). Ctrl-D or exit leaves.

This text lives in helpfile.f. Copy it to your config directory
(~/.config/galileo-cnc/helpfile.f, or $GALILEO_CNC_HOME/helpfile.f) and edit
the copy: it wins over the shipped one. A line holding only [name] starts the
help for the command `name`.

Commands:

[help]
help [COMMAND]
    Print this help, or only the part about COMMAND (help getg).

[getg]
getg [FILE]
    Plot a Gerber (RS-274X) or G-code file. Without FILE it asks for one
    (Tab completes paths). It shows the smallest X and Y the artwork uses and
    proposes offsets that move the artwork to the origin plus a 1 mm margin:
    answer Enter or y to use them, n to type your own "X,Y" in mm (or nothing
    to keep the file's coordinates). It then plans the job (a move outside the
    travel is refused, naming the file line and the axis), shows the number of
    machine commands and the estimated time, and streams it with a progress
    bar. When the artwork switches aperture the bell rings and it asks for the
    pen of that aperture: insert it and press Enter. q or Ctrl-C stops the job;
    `resume` continues it later. At the end: "process has finished" and the
    time taken.

[setup]
setup
    1) Jog: asks for a distance in units of 10 um (1000 = 1 cm, as the
       original Galileo console), then moves the head with the numeric keypad:
         7 / 1   Z up / down        8 / 2   Y + / -        4 / 6   X - / +
       (with NumLock off, Home/End and the arrow keys do the same).
       0 or o makes the current position the origin; q leaves.
    2) Feed rate in mm/s. Above 6.25 mm/s (300 rpm) the motors may lose
       steps: you are warned and asked to confirm. Rates outside the
       machine's limits are refused.

[status]
status
    Print the machine's state (idle, run, hold, alarm, homing) and the head
    position in mm and steps.

[ports]
ports
    List the serial ports, known boards first; * marks the connected one.

[connect]
connect [PORT]
    Reconnect, to PORT if given (COM3, /dev/ttyACM0, a pty path or a pyserial
    URL such as sim://), else to the first board found (or sim://, the
    built-in simulated machine).

[home]
home
    Drive the axes with end-stop switches to them (Z first, then X, then Y).

[unlock]
unlock
    Leave the alarm state. A homing error (switch already pressed, or not
    found) or a stopped job locks the machine; it refuses motion until you
    unlock it. Check the machine first: the position is kept.

[resume]
resume
    Continue a job that was stopped or lost its port, after the last command
    the machine confirmed; nothing is drawn twice, nothing is skipped.

[exit]
exit
    Leave the console (Ctrl-D does the same).
