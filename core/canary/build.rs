fn main() {
    // memcpy / memset and write(2) come from the C library on this target.
    println!("cargo:rustc-link-arg-bins=-lc");
}
