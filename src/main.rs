fn main() -> std::process::ExitCode {
    moreau::cli::main()
}
