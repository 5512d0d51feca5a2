//! An error with its causes on one line, for log lines: error types name
//! their own context and leave the cause to their `source()`, so the command
//! line prints each cause once, and a log line joins them.

/// `e: cause: cause's cause ...`.
pub fn chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut cur = e.source();
    while let Some(c) = cur {
        s.push_str(": ");
        s.push_str(&c.to_string());
        cur = c.source();
    }
    s
}

#[cfg(test)]
mod tests {
    #[derive(Debug, thiserror::Error)]
    #[error("writing x")]
    struct Outer {
        source: std::io::Error,
    }

    #[test]
    fn each_cause_once() {
        let e = Outer {
            source: std::io::Error::other("disk full"),
        };
        assert_eq!(super::chain(&e), "writing x: disk full");
    }
}
