fn main() {
    std::process::exit(cordis_cli::run(std::env::args_os()));
}
