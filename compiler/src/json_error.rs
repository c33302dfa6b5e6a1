//! serde_json errors as every reader of the tool prints them: the position (line,
//! column) in the reader's own form, then the message — without the `at line L column
//! C` that serde_json appends, which would say the position twice.

/// The message of a serde_json error without its trailing ` at line L column C`
/// (the callers print [`serde_json::Error::line`] and [`serde_json::Error::column`]
/// their own way).
pub fn json_message(e: &serde_json::Error) -> String {
    let text = e.to_string();
    let position = format!(" at line {} column {}", e.line(), e.column());
    match text.strip_suffix(&position) {
        Some(message) => message.to_string(),
        None => text,
    }
}

#[cfg(test)]
mod tests {
    use super::json_message;

    #[test]
    fn the_position_is_said_once() {
        let e = serde_json::from_str::<[u32; 2]>("\n[1, 2, 3]").unwrap_err();
        assert_eq!((e.line(), e.column()), (2, 8));
        assert_eq!(json_message(&e), "trailing characters");
        // An error without a position (I/O) keeps its whole message.
        let io = serde_json::from_reader::<_, u32>(std::io::empty()).unwrap_err();
        assert_eq!(
            json_message(&io),
            io.to_string().replace(" at line 1 column 0", "")
        );
    }
}
