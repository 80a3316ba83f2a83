//! A file's path below the drop directory as text, losslessly.
//!
//! Linux file names are bytes: they need not be UTF-8 and may hold control
//! characters (a newline, an ANSI escape). Stored lossily, two names that
//! differ in one invalid byte collide; stored raw, a control character forges
//! log lines and rewrites an operator's terminal in `tail` and `status`. So
//! each path component is kept as it is when it is plain printable UTF-8,
//! and otherwise escaped: `\` becomes `\\`, and each control character or
//! byte that is not UTF-8 becomes `\xNN`. A plain component holds neither
//! `\\` nor `\x` (one that does is escaped too), so [`decode`] always knows
//! which form it reads. Components are joined with `/`.

use std::ffi::{OsStr, OsString};
use std::os::unix::ffi::{OsStrExt, OsStringExt};
use std::path::{Component, Path, PathBuf};

/// The text form of a relative path: its normal components, each encoded,
/// joined with `/`. `None` for an empty path.
pub fn encode(rel: &Path) -> Option<String> {
    let parts: Vec<String> = rel
        .components()
        .filter_map(|c| match c {
            Component::Normal(s) => Some(encode_component(s)),
            _ => None,
        })
        .collect();
    (!parts.is_empty()).then(|| parts.join("/"))
}

/// The path a text form stands for (the inverse of [`encode`]).
pub fn decode(text: &str) -> PathBuf {
    text.split('/').map(decode_component).collect()
}

fn encode_component(name: &OsStr) -> String {
    match name.to_str() {
        Some(s) if !s.chars().any(char::is_control) && !s.contains("\\\\") && !s.contains("\\x") => {
            s.to_string()
        }
        _ => escape(name.as_bytes()),
    }
}

fn escape(mut bytes: &[u8]) -> String {
    let mut out = String::new();
    while !bytes.is_empty() {
        let (valid, rest) = match std::str::from_utf8(bytes) {
            Ok(s) => (s, &[][..]),
            Err(e) => {
                let (ok, bad) = bytes.split_at(e.valid_up_to());
                let bad_len = e.error_len().unwrap_or(bad.len());
                (std::str::from_utf8(ok).expect("checked"), bad.split_at(bad_len).0)
            }
        };
        for c in valid.chars() {
            match c {
                '\\' => out.push_str("\\\\"),
                c if c.is_control() => {
                    let mut buf = [0; 4];
                    for b in c.encode_utf8(&mut buf).bytes() {
                        out.push_str(&format!("\\x{b:02x}"));
                    }
                }
                c => out.push(c),
            }
        }
        for b in rest {
            out.push_str(&format!("\\x{b:02x}"));
        }
        let used = valid.len() + rest.len();
        bytes = &bytes[used..];
    }
    out
}

fn decode_component(text: &str) -> OsString {
    if !(text.contains("\\\\") || text.contains("\\x")) {
        return OsString::from(text);
    }
    let b = text.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = b
            .get(i + 2..i + 4)
            .and_then(|h| u8::from_str_radix(std::str::from_utf8(h).ok()?, 16).ok());
        match (b[i], b.get(i + 1), hex) {
            (b'\\', Some(b'\\'), _) => {
                out.push(b'\\');
                i += 2;
            }
            (b'\\', Some(b'x'), Some(byte)) => {
                out.push(byte);
                i += 4;
            }
            (c, _, _) => {
                out.push(c);
                i += 1;
            }
        }
    }
    OsString::from_vec(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn os(bytes: &[u8]) -> PathBuf {
        PathBuf::from(OsStr::from_bytes(bytes))
    }

    #[test]
    fn plain_names_are_unchanged() {
        for p in [
            "a/b.png",
            "402-127-N55-WW-1_2019-05-10_09-18-07.937_Vis_SV_108.jpg",
            "x\\y.png",
            "é/ü.png",
        ] {
            assert_eq!(encode(Path::new(p)).as_deref(), Some(p));
            assert_eq!(decode(p), Path::new(p));
        }
        assert_eq!(encode(Path::new("")), None);
    }

    #[test]
    fn names_differing_in_one_invalid_byte_stay_apart() {
        let a = os(b"P1_2019-05-10_09-18-07_Vis_SV_0\xff.png");
        let b = os(b"P1_2019-05-10_09-18-07_Vis_SV_0\xfe.png");
        let (ta, tb) = (encode(&a).unwrap(), encode(&b).unwrap());
        assert_ne!(ta, tb);
        assert_eq!(ta, "P1_2019-05-10_09-18-07_Vis_SV_0\\xff.png");
        assert_eq!((decode(&ta), decode(&tb)), (a, b));
    }

    #[test]
    fn control_characters_in_any_component_are_escaped_and_round_trip() {
        let p = os(b"day\n1\x1b[31m/sub\rdir/P1_2019-05-10_09-18-07_Vis_SV_0.png");
        let t = encode(&p).unwrap();
        assert_eq!(
            t,
            "day\\x0a1\\x1b[31m/sub\\x0ddir/P1_2019-05-10_09-18-07_Vis_SV_0.png"
        );
        assert!(!t.chars().any(char::is_control));
        assert_eq!(decode(&t), p);
    }

    #[test]
    fn names_that_look_escaped_are_escaped_themselves() {
        for raw in [&b"a\\xff.png"[..], b"a\\\\b.png", b"tail\\", b"\\x0"] {
            let p = os(raw);
            let t = encode(&p).unwrap();
            assert_eq!(decode(&t), p, "{t}");
        }
        assert_eq!(encode(&os(b"a\\xff.png")).unwrap(), "a\\\\xff.png");
    }
}
