//! The interpreter's hot path does not allocate: after the first lines have sized its
//! reused buffers, resolving further lines and arcs allocates nothing.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use kerf_gcode::{Dialect, Interpreter, Item, Settings};

/// Counts allocations made by the current thread, so that tests running in parallel on
/// other threads do not disturb the count.
struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

// SAFETY: every call is forwarded unchanged to the system allocator; the counter is a
// thread-local `Cell` that does not allocate.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        // SAFETY: the caller upholds `GlobalAlloc::alloc`'s contract, which we pass on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `System` with `layout` through `alloc` above.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        // SAFETY: forwarded unchanged; the caller upholds `GlobalAlloc::realloc`'s contract.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations() -> u64 {
    ALLOCATIONS.with(Cell::get)
}

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
        let before = allocations();
        let mut moves = 0u64;
        for item in it.by_ref() {
            match item {
                Ok(Item::Move(_)) => moves += 1,
                Ok(Item::Event(_)) => {}
                Err(e) => panic!("{dialect:?}: {e}"),
            }
        }
        let after = allocations();
        assert!(moves > 1000, "{dialect:?}");
        assert_eq!(
            after - before,
            0,
            "{dialect:?}: allocations on the hot path"
        );
    }
}
