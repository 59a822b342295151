//! README's test command is the one CI runs.

/// The command in the "Run the tests" section of README.md.
fn readme_test_command(readme: &str) -> Option<String> {
    let section = readme.split("## Run the tests").nth(1)?;
    let block = section.split("```sh").nth(1)?.split("```").next()?;
    block.lines().map(str::trim).find(|line| !line.is_empty()).map(str::to_string)
}

#[test]
fn ci_runs_the_readme_test_command() {
    let root = env!("CARGO_MANIFEST_DIR");
    let readme = std::fs::read_to_string(format!("{root}/README.md")).unwrap();
    let ci = std::fs::read_to_string(format!("{root}/.ci/run")).unwrap();
    let command = readme_test_command(&readme).expect("README has a test command");
    assert!(command.starts_with("cargo test"), "{command}");
    let last = ci.lines().map(str::trim).filter(|l| !l.is_empty() && !l.starts_with('#')).last().unwrap();
    assert_eq!(last, command, ".ci/run must end by running README's test command");
}
