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
getg [--mode ink|centre] [--pens MM,MM] [--layers A,B] [--units mm|in]
     [--optimize] [--side top|bottom] [--drill-marks none|small|actual] [FILE]
    Plot a Gerber (RS-274X), G-code or DXF file. Gerber copper is inked with
    your pens (the profile's, or --pens 0.3,0.8); --mode centre draws each
    object's centre line with one pen per aperture. --layers picks a DXF
    drawing's layers, --units mm|in its units. Gerber and DXF paths are drawn
    in an order that cuts pen-up travel; G-code keeps its own order unless
    --optimize is given (refused, naming the line, for a file that does more
    than draw with a pen: spindle speeds, depths, dwells, tool changes).
    --scale F (0.5, 80%), --rotate 90|180|270 (clockwise) and --fit (the
    largest size that fits the travel, aspect kept) change the drawing
    before the offsets: getg --fit wide.dxf.
    Without FILE it asks for one (Tab completes paths, ~ included). A job
    larger than the machine's travel is refused at once, with both sizes. It
    shows the smallest X and Y the artwork uses and proposes offsets that move
    the whole job (travel moves too) to the origin plus a 1 mm margin: answer
    Enter or y to use them, n to type your own "X,Y" in mm (or nothing to keep
    the file's coordinates). Gerber copper is inked before the question, as
    its fills reach past the centre lines: the offsets asked about are the
    ones the job uses. It then plans the job (a move outside the travel is
    refused, naming the file line, the axis and the distance in mm), shows
    the number of machine commands and the estimated time, and streams it
    with a progress bar. A board whose ink leaves trace pieces out (open
    traces: a centre line would join another copper island) is summed up in
    one line, with the widest pen that draws every trace, and getg asks
    before plotting it (n: nothing is plotted; getg --pens with that pen
    draws them all). When
    the job needs another pen the bell rings and it asks for it ("insert the
    0.8 mm pen"): insert it and press Enter. q or Ctrl-C stops the job (the
    machine ramps down); `resume` continues it. At the end: "process has
    finished" and the time taken; the machine is ready for the next command.
    A board (a folder, .zip or .gbrjob of Gerber and drill files): getg BOARD
    plots the top copper with each hole's centre left bare (--drill-marks
    none|small|actual), then asks you to turn the blank over about the line
    it names on the machine, against a fence, and plots the bottom mirrored
    with the same offsets. --side top|bottom plots one side, --mirror-axis
    x=MM another turn-over line (board mm), --registration adds crosses on
    both sides, --layer FILE=ROLE places a file (galileo-cnc info BOARD).
    A mill job on a GRBL board (docs/mill.md):
    getg --mill isolate|drill|cutout|all [--mill-set KEY=VALUE]
         [--accept-shorts] [--drill-order plated-first|unplated-first] BOARD
    isolates the copper, drills the holes bit by bit or cuts the outline with
    tabs (all: the three, a tool change between), the tool from the profile's
    [mill] with --mill-set over it (--mill-set passes=2). It shows what the
    job does and asks before it runs; islands closer than the tool can part
    are listed in mm and the job is refused unless --accept-shorts. Each
    pause of the job asks like a pen change ("paused for a bit change: put in
    the 1.000 mm bit"): do it, press Enter. On a machine that runs no G-code
    (sim://, this plotter) it is a dry run: the job's paths are plotted with
    the pen (below Z 0 the pen is down), the pauses listed, not waited for.

[preview]
preview [getg's options] [FILE] [-o OUT.png|OUT.svg]
    Write a picture of what getg would plot, without the machine: the
    strokes of each pen over the artwork, the copper the ink leaves bare and
    the ink outside it in colours of their own, drill marks white, a board's
    outline and silk in green and ochre. It uses the offsets getg proposes.
    A board gets one picture per side (NAME-top.png, NAME-bottom.png, the
    bottom mirrored as it is plotted, both with one offset); --side picks
    one. Without -o the pictures are written in the current folder, named
    after the file: preview --silk myboard/ writes myboard-top.png and
    myboard-bottom.png.

[setup]
setup
    1) Jog: asks for a distance in units of 10 um (1000 = 1 cm, as the
       original Galileo console; 0 goes back to the menu), then moves the
       head with the numeric keypad:
         7 / 1   Z up / down        8 / 2   Y + / -        4 / 6   X - / +
       (with NumLock off, Home/End and the arrow keys do the same). The
       position shown follows the head. 0 or o makes the current position
       the origin of all three axes (so Z 0, where the pen now is, becomes
       the drawing height); q leaves. A jog past the travel is refused in
       mm, in the work coordinates the line shows (machine after). A head
       outside the travel (a failed home) may jog back towards it; on GRBL
       only a jog that ends inside, and the refusal says how far. Z has no
       switch: it may go the pen lift below where it was at power-on (a pen
       powered on lifted can be lowered) and stays within its travel's
       length of every height it has had.
    2) Feed rate in mm/s. Above 6.25 mm/s (300 rpm) the motors may lose
       steps: you are warned and asked to confirm. Rates outside the
       machine's limits are refused; the menu stays so you can try again.

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
    built-in simulated machine). If PORT cannot be opened, the working
    connection is kept. A board whose firmware was built for another machine
    profile is named on the connection line and gets no jobs until reflashed.
    A stock GRBL 1.1 board is recognised by its banner ("connected to GRBL
    1.1h on ..."): getg, setup, status, home ($H), unlock ($X) and resume
    work on it too (jogs are $J= moves; q or releasing the key cancels one).
    Its $100-$102 must match the profile's steps/mm, or jobs are refused with
    the lines to send.

[home]
home
    Drive the axes with end-stop switches to them: X, then Y; Z first only
    when the profile gives Z an end stop (z_home_pin); on GRBL, $H as GRBL's
    settings say. The end stops become the origin: an origin set in setup
    before is replaced (the console says so), so set it again where the
    paper is (setup, then o). On GRBL the work origin stays GRBL's G54
    offset from the homed machine frame.

[unlock]
unlock
    Leave the alarm state. A homing error (switch already pressed, or not
    found) locks the machine; it refuses motion and jobs until you unlock
    it. Check the machine first: the position is kept (a seek that found no
    switch ends outside the travel: jog back towards it). Finished and
    stopped jobs do not need it: the console leaves the machine ready itself.

[send]
send LINE
    Send a line to the machine, as UGS, CNCjs or Candle do; a line that
    starts with $ or a G-code word (`$22=1`, `$$`, `G0 X10`) is sent without
    typing send. On GRBL the line goes as it is: GRBL's $ commands ($$, $#,
    $H, $X, $100=160 ...) and G-code; every line GRBL answers is shown, then
    ok or error:N in GRBL's words, and after G-code where GRBL stands once
    still. On our firmware a G-code line runs as a job of one line from
    where the head stands (G91, G20, F and M3/M5 hold for the lines after
    it; the pen lifts at its end; it is not journalled, so `resume` keeps
    an interrupted job); $$ lists the profile's settings, $H homes, $X
    unlocks, other $ commands are GRBL's and are refused.

[resume]
resume
    Continue the last job if it was stopped (q, Ctrl-C) or lost its port.
    It first asks for the pen in force there. A job whose port died goes on
    after the last command the machine ran; a stopped one (the stop lifted
    the pen once the machine stood still) goes back, pen up, to the start of
    the command the machine ramped down in, lowers the pen and draws on from
    there (a few millimetres may be drawn twice, nothing is skipped). It is
    refused, saying why, when the file changed or the machine was moved since
    (its position no longer lies on the job's path). After a reset of the
    board, or when a job started homed (galileo-cnc plot --home) finds the
    machine elsewhere, it homes first; an unhomed job must start again. On a
    GRBL board stopped in this session it goes on from where GRBL kept its
    position; else it homes with $H (or, with no switches, asks you to put
    the pen back at work zero), then goes on after the last line GRBL
    confirmed. An interrupted mill job (getg --mill, plot --mill) goes on
    first: after a reset with no homing you put the tool at the job's work
    zero; a bit change it stopped in is done again.

[exit]
exit
    Leave the console (Ctrl-D does the same).
