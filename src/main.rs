fn main() {
    std::process::exit(noisefree::cli::main());
}
