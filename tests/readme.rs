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

/// README is a front door: short enough to read, lines short enough to diff.
#[test]
fn the_readme_stays_short() {
    let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap();
    let lines: Vec<&str> = readme.lines().collect();
    assert!(lines.len() <= 200, "README.md has {} lines; move detail to docs/", lines.len());
    for (number, line) in lines.iter().enumerate() {
        assert!(
            line.chars().count() <= 200,
            "README.md:{} is {} characters",
            number + 1,
            line.chars().count()
        );
    }
}

/// The relative links of README.md and docs/*.md (`[text](path)`, anchors dropped) lead to files.
#[test]
fn documentation_links_lead_to_files() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut pages = vec![root.join("README.md"), root.join("models/README.md")];
    for entry in std::fs::read_dir(root.join("docs")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "md") {
            pages.push(path);
        }
    }
    let mut checked = 0;
    for page in &pages {
        let text = std::fs::read_to_string(page).unwrap();
        for link in text.split("](").skip(1).filter_map(|rest| rest.split(')').next()) {
            let target = link.split('#').next().unwrap();
            if target.is_empty() || target.contains("://") || target.contains(' ') {
                continue;
            }
            let path = page.parent().unwrap().join(target);
            assert!(path.exists(), "{} links to {link}, which does not exist", page.display());
            checked += 1;
        }
    }
    assert!(checked >= 20, "only {checked} links found: the link syntax this test reads has changed");
}
