//! The interpreter's hot path does not allocate: after the first lines have sized its
//! reused buffers, resolving further lines and arcs allocates nothing.

use kerf_gcode::{Dialect, Interpreter, Item, Settings};

use kerf_testkit::alloc::{Count, CountingAllocator};

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

#[test]
fn resolving_blocks_does_not_allocate() {
    let programs = [
        (
            Dialect::LinuxCnc,
            "G1 X1 Y0 F100 S1000 M3\nG3 X2 Y1 I0 J1\nG2 X3 Y0 R1\nG0 @2 ^10\n",
        ),
        (
            Dialect::Sinumerik,
            "G1 X1 Y0 F100\nG3 X2 Y1 I0 J1\nG2 X3 Y0 CR=1\nG1 RP=2 AP=10\n",
        ),
        (
            Dialect::Heidenhain,
            "G01 X+1 Y+0 F100 *\nI+2 J+0 *\nG13 G91 H+90 *\nG11 R+3 H+10 *\n",
        ),
        (
            Dialect::Fagor,
            "G01 X1 Y0 F100\nG03 X2 Y1 I0 J1\nG01 R2 Q10\n",
        ),
        (
            Dialect::Rockwell,
            "G01 X1 Y0 F100 ; G03 X2 Y1 I0 J1 ; G02 X3 Y0 R1 ;\n",
        ),
    ];
    for (dialect, body) in programs {
        let mut src = body.repeat(2000);
        if dialect == Dialect::LinuxCnc {
            // A LinuxCNC program ends with M2 (else: "File ended with no percent sign or
            // program end").
            src.push_str("M2\n");
        }
        let mut it = Interpreter::new(src.as_bytes(), dialect, Settings::default());
        // Warm-up: the first lines size the reused buffers.
        for item in it.by_ref().take(100) {
            assert!(item.is_ok(), "{dialect:?}: {item:?}");
        }
        let count = Count::start();
        let mut moves = 0u64;
        for item in it.by_ref() {
            match item {
                Ok(Item::Move(_)) => moves += 1,
                Ok(Item::Event(_)) => {}
                Err(e) => panic!("{dialect:?}: {e}"),
            }
        }
        let allocations = count.stop();
        assert!(moves > 1000, "{dialect:?}");
        assert_eq!(allocations, 0, "{dialect:?}: allocations on the hot path");
    }
}
