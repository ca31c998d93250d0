//! Every relative link in README.md and docs/*.md resolves: the file (or folder) exists, and
//! an `#anchor` into a Markdown file names one of its headings. Code comments that cite a
//! page `docs/NAME.md` cite one that exists. Std only: no crate internals, so this test
//! builds in seconds.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The link targets `(...)` of inline Markdown links `[text](target)` outside code blocks and
/// code spans, with the line each is on.
fn link_targets(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut in_fence = false;
    for (n, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            in_fence = !in_fence;
            continue;
        }
        if in_fence {
            continue;
        }
        // Drop code spans: `[a](b)` inside backticks is not a link.
        let mut plain = String::new();
        for (k, part) in line.split('`').enumerate() {
            if k % 2 == 0 {
                plain.push_str(part);
            }
        }
        let mut rest = plain.as_str();
        while let Some(at) = rest.find("](") {
            let after = &rest[at + 2..];
            let end = after.find(')').unwrap_or(after.len());
            // `[text](path "title")`: the target is the first word.
            let target = after[..end].split_whitespace().next().unwrap_or("");
            let target = target.trim_start_matches('<').trim_end_matches('>');
            out.push((n + 1, target.to_string()));
            rest = &after[end..];
        }
    }
    out
}

/// GitHub's anchor for a heading: lower case, punctuation other than `-` and `_` dropped,
/// spaces turned into hyphens.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

/// The anchors of a Markdown file's headings (`#` lines outside code blocks).
fn anchors(text: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut in_fence = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            in_fence = !in_fence;
            continue;
        }
        if !in_fence && line.starts_with('#') {
            let title = line.trim_start_matches('#').replace('`', "");
            let base = slug(&title);
            // Repeated headings get -1, -2, ... as on GitHub.
            let mut name = base.clone();
            let mut k = 0;
            while !out.insert(name.clone()) {
                k += 1;
                name = format!("{base}-{k}");
            }
        }
    }
    out
}

/// Problems with the relative links of the Markdown file `file`, one line each.
fn broken_links(file: &Path) -> Vec<String> {
    let text = fs::read_to_string(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    let dir = file.parent().unwrap();
    let mut problems = Vec::new();
    for (line, target) in link_targets(&text) {
        let lower = target.to_lowercase();
        if target.is_empty()
            || lower.starts_with("http://")
            || lower.starts_with("https://")
            || lower.starts_with("mailto:")
        {
            continue;
        }
        let (path, anchor) = match target.split_once('#') {
            Some((p, a)) => (p, Some(a)),
            None => (target.as_str(), None),
        };
        let resolved = if path.is_empty() { file.to_path_buf() } else { dir.join(path) };
        let at = format!("{}:{line}: ({target})", file.display());
        if !resolved.exists() {
            problems.push(format!("{at}: {} does not exist", resolved.display()));
            continue;
        }
        if let Some(anchor) = anchor
            && resolved.extension().is_some_and(|e| e == "md")
        {
            let headings = anchors(&fs::read_to_string(&resolved).unwrap());
            if !headings.contains(anchor) {
                problems.push(format!("{at}: no heading #{anchor} in {}", resolved.display()));
            }
        }
    }
    problems
}

fn markdown_files() -> Vec<PathBuf> {
    let mut files = vec![root().join("README.md")];
    let mut docs: Vec<PathBuf> = fs::read_dir(root().join("docs"))
        .expect("docs/ exists")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    files.extend(docs);
    files
}

#[test]
fn every_relative_link_in_readme_and_docs_resolves() {
    let files = markdown_files();
    assert!(files.len() > 1, "no pages in docs/");
    let mut checked = 0;
    let mut problems = Vec::new();
    for f in &files {
        checked += link_targets(&fs::read_to_string(f).unwrap()).len();
        problems.extend(broken_links(f));
    }
    assert!(checked > 10, "only {checked} links found: is the link parser broken?");
    assert!(problems.is_empty(), "broken links:\n{}", problems.join("\n"));
}

/// Comments and scripts cite pages as `docs/NAME.md`; each must exist.
#[test]
fn every_docs_page_cited_by_the_code_exists() {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        let Ok(entries) = fs::read_dir(dir) else { return };
        for e in entries {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|e| e == "rs" || e == "py" || e == "cpp" || e == "sh") {
                out.push(p);
            }
        }
    }
    let mut sources = Vec::new();
    for d in ["src", "tests", "benches", "examples", "rooms"] {
        walk(&root().join(d), &mut sources);
    }
    let mut missing = Vec::new();
    let mut cited = 0;
    // This file names `docs/NAME.md` as a pattern, not a page.
    for f in sources.iter().filter(|f| !f.ends_with("tests/docs_links.rs")) {
        let text = fs::read_to_string(f).unwrap_or_default();
        let mut rest = text.as_str();
        while let Some(at) = rest.find("docs/") {
            let name: String = rest[at + 5..]
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '-' || *c == '_' || *c == '.')
                .collect();
            rest = &rest[at + 5..];
            let page = name.trim_end_matches('.');
            if !page.ends_with(".md") {
                continue;
            }
            cited += 1;
            if !root().join("docs").join(page).exists() {
                missing.push(format!("{}: docs/{page}", f.display()));
            }
        }
    }
    assert!(cited > 0, "no docs/ citations found: is the scan broken?");
    assert!(missing.is_empty(), "cited pages that do not exist:\n{}", missing.join("\n"));
}

/// The checker itself: a broken file link and a wrong anchor are reported, good ones and
/// links in code are not.
#[test]
fn the_checker_reports_broken_links() {
    let dir = std::env::temp_dir().join(format!("propsim_docs_links_{}", std::process::id()));
    fs::create_dir_all(&dir).unwrap();
    fs::write(dir.join("b.md"), "# A Heading: `with` code\n\n## Twice\n## Twice\n").unwrap();
    let a = dir.join("a.md");
    fs::write(
        &a,
        "[ok](b.md) [ok](b.md#a-heading-with-code) [ok](b.md#twice-1) [web](https://x.invalid/y)\n\
         [gone](missing.md) [bad anchor](b.md#nowhere) `[in code](nope.md)`\n\
         ```\n[in a block](nope.md)\n```\n",
    )
    .unwrap();
    let problems = broken_links(&a);
    fs::remove_dir_all(&dir).unwrap();
    assert_eq!(problems.len(), 2, "{problems:#?}");
    assert!(problems[0].contains("missing.md") && problems[0].contains("does not exist"));
    assert!(problems[1].contains("#nowhere"));
}
