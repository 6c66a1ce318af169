fn main() {
    // A reader that stops early (`relume compare uncertainty ... | head`) ends relume
    // quietly, as it ends any Unix filter; Rust ignores SIGPIPE by default, and println!
    // then panics on the broken pipe. Every file relume writes is written atomically, so
    // no partial output is left behind.
    #[cfg(unix)]
    // SAFETY: called first, before any other thread exists; it only restores the
    // default action of one signal.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    if let Err(e) = relume::fsutil::remove_staged_files_on_interrupt() {
        eprintln!(
            "relume: warning: cannot catch Ctrl-C ({e}): an interrupted run may leave hidden .<name>.tmp-<pid> files beside its outputs"
        );
    }
    std::process::exit(relume::cli::main());
}
