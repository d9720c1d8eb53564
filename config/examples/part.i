%PART G71 *
; Kerf example part, Heidenhain TNC ISO dialect: the part of part.ngc, a 100 x 60 mm
; plate, top at Z0: facing, a pocket entered by a helix, a drilled bolt pattern.
; Run it with: kerf sim config/examples/part.i --out part.csv
N10 G17 G90 *
N20 T1 G17 S8000 *
N30 M3 *
N40 M8 *
; Facing at Z-0.5: zig-zag passes 8 mm apart, overhanging the stock by the tool radius
N50 G00 Z+5 *
N60 G00 X-8 Y+0 *
N70 G01 Z-0.5 F300 *
N80 G01 X+108 F1200 *
N90 G01 Y+8 *
N100 G01 X-8 *
N110 G01 Y+16 *
N120 G01 X+108 *
N130 G01 Y+24 *
N140 G01 X-8 *
N150 G01 Y+32 *
N160 G01 X+108 *
N170 G01 Y+40 *
N180 G01 X-8 *
N190 G01 Y+48 *
N200 G01 X+108 *
N210 G01 Y+56 *
N220 G01 X-8 *
N230 G01 Y+60 *
N240 G01 X+108 *
N250 G00 Z+5 *
; Pocket 40 x 24 x 3 mm with R8 corners, centred at X50 Y30
; Helical entry: two turns of radius 3 about the pocket centre from Z0 down to Z-3
N260 G00 X+53 Y+30 *
N270 G01 Z+0 F300 *
N280 I+50 J+30 *
N290 G03 X+53 Y+30 Z-1.5 F400 *
N300 G03 X+53 Y+30 Z-3 *
; Clear the middle, then the finishing contour of the tool centre: 30 x 14 with R3 corners
N310 G01 X+60 Y+30 F800 *
N320 G01 X+40 *
N330 G01 X+50 Y+23 *
N340 G01 X+62 *
N350 I+62 J+26 *
N360 G03 X+65 Y+26 *
N370 G01 Y+34 *
N380 I+62 J+34 *
N390 G03 X+62 Y+37 *
N400 G01 X+38 *
N410 I+38 J+34 *
N420 G03 X+35 Y+34 *
N430 G01 Y+26 *
N440 I+38 J+26 *
N450 G03 X+38 Y+23 *
N460 G01 X+50 *
N470 G01 Y+30 *
N480 G00 Z+5 *
; Bolt pattern: four holes 6 mm deep, 10 mm in from the corners
N490 G00 X+10 Y+10 *
N500 G01 Z-6 F150 *
N510 G00 Z+5 *
N520 G00 X+90 *
N530 G01 Z-6 *
N540 G00 Z+5 *
N550 G00 Y+50 *
N560 G01 Z-6 *
N570 G00 Z+5 *
N580 G00 X+10 *
N590 G01 Z-6 *
N600 G00 Z+5 *
N610 M9 *
N620 M5 *
N630 G00 Z+25 *
N640 G00 X+0 Y+0 *
N650 M30 *
N99999 %PART G71 *
