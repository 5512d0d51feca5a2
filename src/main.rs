fn main() -> std::process::ExitCode {
    sagnac::cli::main()
}
