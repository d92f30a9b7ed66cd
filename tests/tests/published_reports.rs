//! The reports published under `docs/results/` are whole: every file a page references
//! (images, animations, linked pages and results) is in the repository beside it, and no
//! page reaches for the network.

use std::path::{Path, PathBuf};

fn pages(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            pages(&p, out);
        } else if p.extension().is_some_and(|x| x == "html") {
            out.push(p);
        }
    }
}

#[test]
fn every_published_report_references_only_files_that_exist() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/results");
    let mut found = Vec::new();
    pages(&root, &mut found);
    assert!(found.len() >= 2, "no reports under {}", root.display());
    for page in found {
        let html = std::fs::read_to_string(&page).unwrap();
        assert!(html.starts_with("<!DOCTYPE html>"), "{}", page.display());
        for f in dips_report::html::referenced_files(&html) {
            if f.starts_with('#') {
                continue;
            }
            assert!(
                !f.contains("://"),
                "{} reaches the network: {f}",
                page.display()
            );
            let target = page.parent().unwrap().join(&f);
            assert!(
                target.is_file(),
                "{} references missing {f}",
                page.display()
            );
        }
    }
}
