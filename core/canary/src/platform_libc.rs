//! The canary on this machine: libc's `main`, `write` to stdout and `abort` on a panic.
//! No std: the core's graph linking std would fail the build with a duplicate
//! `panic_impl`.

extern "C" {
    fn write(fd: i32, buf: *const u8, count: usize) -> isize;
    fn abort() -> !;
}

/// Writes `bytes` to stdout.
pub fn print(bytes: &[u8]) {
    // SAFETY: `bytes` is a valid buffer for its length; fd 1 is stdout.
    unsafe {
        write(1, bytes.as_ptr(), bytes.len());
    }
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    print(b"relume-core canary: panicked\n");
    // SAFETY: abort takes no arguments and does not return.
    unsafe { abort() }
}

#[cfg(debug_assertions)]
#[unsafe(no_mangle)]
pub extern "C" fn rust_eh_personality() {}

#[unsafe(no_mangle)]
pub extern "C" fn main(_argc: i32, _argv: *const *const u8) -> i32 {
    if crate::run() {
        0
    } else {
        1
    }
}
