//! The documentation cannot rot: every relative link in README.md and
//! docs/**/*.md points at a file of the tree (and, into a Markdown file, at
//! a heading it has), and every host-tools command the pages name (`host-tools
//! SUB ...`, `cargo run ... -p host-tools -- SUB ...`, and an inline span
//! that begins with a subcommand and names a flag, `train --sign`) uses a
//! subcommand and flags the built binary has. The subcommands and their flags are read from
//! the binary's own `--help`, so a page is checked against the tools as they
//! are, never against a list kept here.
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Commands a page may name before the tools have them: (page, subcommand),
/// honoured only while `host-tools --help` does not list the subcommand.
const PENDING: &[(&str, &str)] = &[];

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// README.md and every Markdown file under docs/, as paths relative to the
/// repository root with `/` separators.
fn pages() -> Vec<String> {
    fn walk(dir: &Path, rel: &str, out: &mut Vec<String>) {
        let mut entries: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap()).collect();
        entries.sort_by_key(|e| e.file_name());
        for e in entries {
            let name = e.file_name().to_string_lossy().into_owned();
            let rel = format!("{rel}/{name}");
            if e.file_type().unwrap().is_dir() {
                walk(&e.path(), &rel, out);
            } else if name.ends_with(".md") {
                out.push(rel);
            }
        }
    }
    let mut out = vec!["README.md".to_string()];
    walk(&root().join("docs"), "docs", &mut out);
    out
}

/// A page split into its prose (code removed) and its code: fenced blocks,
/// indented blocks and inline code spans (a span may run over a line break).
struct Split {
    prose: String,
    code: Vec<String>,
    /// The inline code spans (also in `code`).
    spans: Vec<String>,
    headings: Vec<String>,
}

fn split(text: &str) -> Split {
    let mut prose = String::new();
    let mut code = Vec::new();
    let mut headings = Vec::new();
    let mut fence: Option<String> = None;
    let mut prev_blank = true;
    let mut in_indented = false;
    for line in text.lines() {
        let trimmed = line.trim_start();
        if let Some(f) = &fence {
            if trimmed.starts_with(f.as_str()) {
                fence = None;
            } else {
                code.push(line.to_string());
            }
            continue;
        }
        if trimmed.starts_with("```") || trimmed.starts_with("~~~") {
            fence = Some(trimmed[..3].to_string());
            continue;
        }
        let indented = line.starts_with("    ") || line.starts_with('\t');
        if indented && (prev_blank || in_indented) && !line.trim().is_empty() {
            in_indented = true;
            code.push(line.to_string());
            continue;
        }
        if !line.trim().is_empty() {
            in_indented = false;
        }
        prev_blank = line.trim().is_empty();
        if line.starts_with('#') {
            headings.push(line.trim_start_matches('#').trim().to_string());
        }
        prose.push_str(line);
        prose.push('\n');
    }
    // Inline code spans, taken out of the prose.
    let mut rest = String::new();
    let mut spans = Vec::new();
    let mut chars = prose.char_indices().peekable();
    let bytes = prose.as_bytes();
    while let Some((i, c)) = chars.next() {
        if c != '`' {
            rest.push(c);
            continue;
        }
        let mut ticks = 1;
        while chars.peek().is_some_and(|&(_, c)| c == '`') {
            chars.next();
            ticks += 1;
        }
        let open = "`".repeat(ticks);
        let start = i + ticks;
        match prose[start..].find(&open) {
            Some(len) if !prose[start..start + len].contains("\n\n") => {
                spans.push(prose[start..start + len].replace('\n', " "));
                let end = start + len + ticks;
                while chars.peek().is_some_and(|&(j, _)| j < end) {
                    chars.next();
                }
            }
            _ => rest.push_str(std::str::from_utf8(&bytes[i..start]).unwrap()),
        }
    }
    code.extend(spans.iter().cloned());
    Split { prose: rest, code, spans, headings }
}

/// GitHub's anchor for a heading: lower case, markup and punctuation other
/// than `-` and `_` dropped, spaces to `-`; a repeated heading gets `-1`, `-2`.
fn anchors(headings: &[String]) -> BTreeSet<String> {
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    let mut out = BTreeSet::new();
    for h in headings {
        let slug: String = h
            .to_lowercase()
            .chars()
            .filter_map(|c| match c {
                ' ' => Some('-'),
                c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
                _ => None,
            })
            .collect();
        let n = seen.entry(slug.clone()).or_insert(0);
        out.insert(if *n == 0 { slug.clone() } else { format!("{slug}-{n}") });
        *n += 1;
    }
    out
}

/// The targets of the Markdown links and images in prose: `[text](target)`
/// and `![alt](target)`, with an optional title after the target dropped.
fn link_targets(prose: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(at) = prose[from..].find("](") {
        let start = from + at + 2;
        let Some(len) = prose[start..].find(')') else { break };
        let target = prose[start..start + len].split_whitespace().next().unwrap_or("");
        out.push(target.trim_matches(|c| c == '<' || c == '>').to_string());
        from = start + len;
    }
    out
}

/// Resolves `a/b/../c` without touching the file system.
fn normalise(path: &str) -> String {
    let mut parts: Vec<&str> = Vec::new();
    for p in path.split('/') {
        match p {
            "" | "." => {}
            ".." => {
                parts.pop();
            }
            p => parts.push(p),
        }
    }
    parts.join("/")
}

/// What `host-tools ... --help` says: its subcommands and its flags.
#[derive(Default)]
struct Help {
    subcommands: BTreeSet<String>,
    flags: BTreeSet<String>,
}

fn help(args: &[&str]) -> Help {
    let out = Command::new(env!("CARGO_BIN_EXE_host-tools")).args(args).arg("--help").output().unwrap();
    assert!(out.status.success(), "host-tools {} --help failed", args.join(" "));
    let text = String::from_utf8(out.stdout).unwrap();
    let mut h = Help::default();
    let mut section = "";
    for line in text.lines() {
        if !line.starts_with(' ') && line.ends_with(':') {
            section = line;
            continue;
        }
        let t = line.trim_start();
        if section == "Commands:"
            && line.starts_with("  ")
            && !line.starts_with("    ")
            && let Some(name) = t.split_whitespace().next()
        {
            h.subcommands.insert(name.to_string());
        }
        if t.starts_with('-') {
            for word in t.split([' ', ',', '=', '[', '<']) {
                if let Some(flag) = word.strip_prefix("--").filter(|f| !f.is_empty()) {
                    h.flags.insert(flag.to_string());
                }
            }
        }
    }
    h
}

/// Every host-tools command line in a piece of code: the words after the
/// subcommand up to a comment or a shell operator.
fn commands(code: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    for line in code.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        for (i, w) in words.iter().enumerate() {
            if *w != "host-tools" {
                continue;
            }
            // `cargo run ... -p host-tools -- SUB` or `host-tools SUB`; not
            // `-p host-tools --test NAME`, `--example`, `--bench`.
            let after = if words.get(i + 1) == Some(&"--") { i + 2 } else { i + 1 };
            let via_cargo = i > 0 && words[i - 1] == "-p";
            if via_cargo && words.get(i + 1) != Some(&"--") {
                continue;
            }
            let Some(sub) = words.get(after) else { continue };
            if sub.starts_with('-') || !sub.chars().next().is_some_and(|c| c.is_ascii_lowercase()) {
                continue;
            }
            let cmd: Vec<String> = words[after..]
                .iter()
                .take_while(|w| !matches!(**w, "#" | "|" | "&&" | ";" | ">" | "2>" | "then" | "or"))
                .map(|w| w.to_string())
                .collect();
            out.push(cmd);
        }
    }
    out
}

/// An inline span written as a command without `host-tools` in front
/// (`train --sign`, `pixel-map --false-alarm 0.10`): its words, when the
/// first is one of `subcommands` and a later one is a flag.
fn bare_command(span: &str, subcommands: &BTreeSet<String>) -> Option<Vec<String>> {
    let words: Vec<String> = span.split_whitespace().map(str::to_string).collect();
    let first = words.first()?;
    (subcommands.contains(first) && words[1..].iter().any(|w| w.starts_with("--"))).then_some(words)
}

/// The flags a command line names: `--name`, `--name=value`, `[--name`.
fn flags_of(words: &[String]) -> Vec<String> {
    words
        .iter()
        .filter_map(|w| {
            let w = w.trim_start_matches(['[', '(', '`']);
            let name = w.strip_prefix("--")?;
            let name: String = name.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '-').collect();
            (!name.is_empty()).then_some(name)
        })
        .collect()
}

#[test]
fn every_link_and_command_in_the_docs_exists() {
    let root = root();
    let pages = pages();
    let mut texts = BTreeMap::new();
    for p in &pages {
        texts.insert(p.clone(), split(&std::fs::read_to_string(root.join(p)).unwrap()));
    }
    let mut problems = Vec::new();

    // Links.
    for (page, s) in &texts {
        let dir = page.rsplit_once('/').map_or("", |(d, _)| d);
        for target in link_targets(&s.prose) {
            if target.contains("://") || target.starts_with("mailto:") || target.is_empty() {
                continue;
            }
            let (file, anchor) = target.split_once('#').unwrap_or((&target, ""));
            let path = if file.is_empty() { page.clone() } else { normalise(&format!("{dir}/{file}")) };
            if !root.join(&path).exists() {
                problems.push(format!("{page}: link to {target}: no file {path}"));
                continue;
            }
            if !anchor.is_empty() && path.ends_with(".md") {
                let headings = match texts.get(&path) {
                    Some(s) => anchors(&s.headings),
                    None => anchors(&split(&std::fs::read_to_string(root.join(&path)).unwrap()).headings),
                };
                if !headings.contains(anchor) {
                    problems.push(format!("{page}: link to {target}: {path} has no heading #{anchor}"));
                }
            }
        }
    }

    // Commands.
    let top = help(&[]);
    let mut helps: BTreeMap<Vec<String>, Help> = BTreeMap::new();
    let mut pending_used = BTreeSet::new();
    for (page, s) in &texts {
        let bare =
            s.spans.iter().filter(|c| !c.contains("host-tools")).filter_map(|c| bare_command(c, &top.subcommands));
        for cmd in s.code.iter().flat_map(|c| commands(c)).chain(bare) {
            {
                let sub = &cmd[0];
                if !top.subcommands.contains(sub) {
                    if let Some(entry) = PENDING.iter().find(|(p, c)| p == page && c == sub) {
                        pending_used.insert(*entry);
                    } else {
                        problems.push(format!("{page}: `host-tools {}`: no subcommand {sub}", cmd.join(" ")));
                    }
                    continue;
                }
                // A subcommand with subcommands of its own takes the next word.
                let mut path = vec![sub.clone()];
                let key = |p: &Vec<String>| p.clone();
                let h = helps.entry(key(&path)).or_insert_with(|| help(&[sub.as_str()]));
                if !h.subcommands.is_empty() {
                    match cmd.get(1).filter(|w| h.subcommands.contains(*w)) {
                        Some(w) => path.push(w.clone()),
                        None => {
                            problems.push(format!(
                                "{page}: `host-tools {}`: {sub} needs one of its subcommands",
                                cmd.join(" ")
                            ));
                            continue;
                        }
                    }
                }
                let args: Vec<&str> = path.iter().map(String::as_str).collect();
                let h = helps.entry(path.clone()).or_insert_with(|| help(&args));
                for f in flags_of(&cmd[path.len()..]) {
                    if !h.flags.contains(&f) {
                        problems.push(format!(
                            "{page}: `host-tools {}`: {} has no flag --{f}",
                            cmd.join(" "),
                            path.join(" ")
                        ));
                    }
                }
            }
        }
    }
    for entry @ (page, sub) in PENDING {
        if top.subcommands.contains(*sub) {
            problems
                .push(format!("host-tools has `{sub}` now: remove the PENDING entry ({page}, {sub}) in {}", file!()));
        } else if !pending_used.contains(entry) {
            problems.push(format!("PENDING entry ({page}, {sub}) is not used by any command: remove it"));
        }
    }
    assert!(problems.is_empty(), "{} problem(s) in the docs:\n{}", problems.len(), problems.join("\n"));
}

#[test]
fn the_checker_reads_links_commands_and_anchors_as_github_does() {
    let s = split(
        "# The measurement rate (`rate`)\n\nSee [a](b.md#c) and `host-tools train --zones 4\n--out x`.\n\n    cargo run --release -p host-tools -- measure --tcp A --lines 4   # note --not-a-flag\n    cargo test --release -p host-tools --test stability\n",
    );
    assert_eq!(link_targets(&s.prose), ["b.md#c"]);
    assert!(anchors(&s.headings).contains("the-measurement-rate-rate"));
    let mut cmds: Vec<Vec<String>> = s.code.iter().flat_map(|c| commands(c)).collect();
    cmds.sort();
    assert_eq!(cmds.len(), 2, "{cmds:?}");
    assert_eq!(cmds[0][0], "measure");
    assert_eq!(flags_of(&cmds[0]), ["tcp", "lines"]);
    assert_eq!(flags_of(&cmds[1]), ["zones", "out"]);
    let train = help(&["train"]);
    assert!(train.flags.contains("zones") && train.flags.contains("sign") && !train.flags.contains("not-a-flag"));
    assert!(help(&[]).subcommands.contains("measure"));
    assert_eq!(normalise("docs/guide/../point-schema.md"), "docs/point-schema.md");
    let subs = help(&[]).subcommands;
    assert_eq!(bare_command("tradeoff --qemu", &subs).unwrap(), ["tradeoff", "--qemu"]);
    for not_a_command in ["train", "cargo test --release", "the train --zones", "measure"] {
        assert_eq!(bare_command(not_a_command, &subs), None, "{not_a_command}");
    }
}
