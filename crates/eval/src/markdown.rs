//! The report's Markdown: user text (scene, model and file names) written into it as text,
//! never as markup, and the HTML rendered from the same Markdown by pulldown-cmark, so the
//! two files cannot disagree about what a name says.

use pulldown_cmark::{html, Options, Parser};

/// `s` as literal Markdown text: line breaks as spaces, and backslash-escaped (CommonMark
/// allows it for any ASCII punctuation) every character that can open markup: a table cell, a
/// link or image, emphasis, code, raw HTML, an entity, and at the start a heading, quote or
/// list. Punctuation that opens nothing on its own stays as written, so names stay readable.
pub fn text(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let leading_digits = s.chars().take_while(char::is_ascii_digit).count();
    for (i, c) in s.chars().enumerate() {
        // "1." or "1)" at the start would open an ordered list.
        let ends_list_number = i == leading_digits && i > 0 && matches!(c, '.' | ')');
        match c {
            '\n' | '\r' | '\t' => out.push(' '),
            ',' | '.' | ':' | ';' | '/' | '\'' | '"' | '?' | '%' | '=' | '@' | '$' | '(' | ')' if !ends_list_number => out.push(c),
            c if c.is_ascii_punctuation() => {
                out.push('\\');
                out.push(c);
            }
            c => out.push(c),
        }
    }
    out
}

/// `s` as a code span: fenced by one backtick more than its longest run of backticks, padded
/// where it starts or ends with one (CommonMark's rule), its line breaks as spaces.
pub fn code(s: &str) -> String {
    let s: String = s.chars().map(|c| if matches!(c, '\n' | '\r') { ' ' } else { c }).collect();
    let longest = s.split(|c| c != '`').map(str::len).max().unwrap_or(0);
    let fence = "`".repeat(longest + 1);
    let pad = if s.starts_with('`') || s.ends_with('`') { " " } else { "" };
    format!("{fence}{pad}{s}{pad}{fence}")
}

/// The HTML of a Markdown fragment (GitHub tables on).
pub fn to_html(markdown: &str) -> String {
    let mut out = String::new();
    html::push_html(&mut out, Parser::new_ext(markdown, Options::ENABLE_TABLES));
    out
}

/// `s` escaped for HTML text and attribute values.
pub fn html_text(s: &str) -> String {
    let mut out = String::new();
    pulldown_cmark_escape::escape_html(&mut out, s).expect("writing to a String cannot fail");
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Names built to break out: every ASCII punctuation character alone, at the start and
    /// inside a word, markup that opens each construct, and random strings over an alphabet
    /// of punctuation, letters, spaces and line breaks.
    fn hostile_names() -> Vec<String> {
        let punctuation: Vec<char> = (0u8..128).map(char::from).filter(char::is_ascii_punctuation).collect();
        let mut names: Vec<String> = punctuation.iter().flat_map(|&c| [c.to_string(), format!("{c}name"), format!("na{c}me"), format!("name{c}{c}")]).collect();
        names.extend(
            [
                "<script>alert(1)</script>",
                "[link](javascript:alert(1))",
                "![image](x.png)",
                "a | b | c",
                "**bold** and _em_",
                "``code`` `x`",
                "# heading",
                "> quote",
                "- item",
                "1. first",
                "12) twelfth",
                "line\nbreak\n\n# heading",
                "&amp; &lt;",
                "back\\slash\\",
                "<http://example.com>",
                "---",
            ]
            .map(String::from),
        );
        let alphabet: Vec<char> = punctuation.iter().copied().chain("ab1 \n".chars()).collect();
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        for _ in 0..2000 {
            let len = rng.random_range(1..12);
            names.push((0..len).map(|_| alphabet[rng.random_range(0..alphabet.len())]).collect());
        }
        names
    }

    /// What a reader should see: the name with its line breaks as spaces, escaped for HTML,
    /// without the whitespace Markdown trims at either end.
    fn shown(name: &str) -> String {
        body_text(name.replace(['\n', '\r', '\t'], " ").trim())
    }

    /// HTML text as pulldown-cmark writes it between tags (quotes left as they are).
    fn body_text(s: &str) -> String {
        let mut out = String::new();
        pulldown_cmark_escape::escape_html_body_text(&mut out, s).unwrap();
        out
    }

    #[test]
    fn text_renders_as_the_name_itself_in_a_paragraph_a_list_and_a_table() {
        for name in hostile_names() {
            let escaped = text(&name);
            if shown(&name).is_empty() {
                continue;
            }
            assert_eq!(to_html(&escaped).trim(), format!("<p>{}</p>", shown(&name)), "paragraph of {name:?}");
            assert_eq!(to_html(&format!("- {escaped}")).trim(), format!("<ul>\n<li>{}</li>\n</ul>", shown(&name)), "list item of {name:?}");
            let table = to_html(&format!("| model | value |\n|---|---|\n| {escaped} | 1 |\n"));
            assert!(table.contains(&format!("<td>{}</td><td>1</td>", shown(&name))), "table row of {name:?}: {table}");
        }
    }

    #[test]
    fn code_spans_hold_the_name_whatever_backticks_it_holds() {
        for name in hostile_names() {
            let rendered = to_html(&format!("x {} y", code(&name)));
            let inner = name.replace(['\n', '\r'], " ");
            // CommonMark strips one space from each end of a code span that has both.
            let stripped = inner.strip_prefix(' ').and_then(|s| s.strip_suffix(' ')).filter(|_| !inner.trim().is_empty());
            let expected = [body_text(&inner), body_text(stripped.unwrap_or(&inner))];
            assert!(expected.iter().any(|e| rendered.contains(&format!("<code>{e}</code>"))), "code span of {name:?}: {rendered}");
        }
    }
}
