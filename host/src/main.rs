fn main() {
    std::process::exit(relume::cli::main());
}
