//! The canary on a bare Cortex-M4F (thumbv7em-none-eabihf): cortex-m-rt's reset handler,
//! output and exit status through semihosting (QEMU's `-semihosting`, or a debugger on a
//! board). After the run it reports how much of the stack the renderer and the solver
//! used: cortex-m-rt's `paint-stack` fills the stack with a known word before `main`, and
//! the deepest word no longer holding it is as deep as the stack went.

use cortex_m_rt::{entry, STACK_PAINT_VALUE};
use cortex_m_semihosting::{debug, hio};

/// The stack the canary may use, in bytes: what a small Cortex-M4F part leaves of its RAM
/// (memory.x gives the canary 256 KiB in all). Past it the run fails.
const STACK_BUDGET: usize = 128 * 1024;

/// Writes `bytes` to the host's stdout; dropped when no host listens.
pub fn print(bytes: &[u8]) {
    if let Ok(mut out) = hio::hstdout() {
        let _ = out.write_all(bytes);
    }
}

/// Where the program ends when no debugger takes the semihosting exit (a board on its own).
fn halt() -> ! {
    loop {
        core::hint::spin_loop();
    }
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    print(b"relume-core canary: panicked\n");
    debug::exit(debug::EXIT_FAILURE);
    halt()
}

extern "C" {
    /// The top of the stack (its first word lies below).
    static _stack_start: u32;
    /// The lowest address the stack may reach: the end of the statically allocated RAM.
    static _stack_end: u32;
}

/// Bytes of the stack written since reset: from its top down to the deepest word that
/// no longer holds the paint.
fn stack_used() -> usize {
    let top = core::ptr::addr_of!(_stack_start) as usize;
    let bottom = core::ptr::addr_of!(_stack_end) as usize;
    let mut address = bottom;
    while address < top {
        // SAFETY: every word from `_stack_end` up to `_stack_start` is RAM of the stack.
        let word = unsafe { core::ptr::read_volatile(address as *const u32) };
        if word != STACK_PAINT_VALUE {
            break;
        }
        address += 4;
    }
    top - address
}

#[entry]
fn main() -> ! {
    let recovered = crate::run();
    let used = stack_used();
    crate::Line::new("relume-core canary: stack used ")
        .number(used as f64 / 1024.0)
        .text(" KiB of a budget of ")
        .number(STACK_BUDGET as f64 / 1024.0)
        .text(" KiB")
        .print();
    let within = used <= STACK_BUDGET;
    if !within {
        crate::Line::new("relume-core canary: the stack went past its budget").print();
    }
    debug::exit(if recovered && within {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    halt()
}
