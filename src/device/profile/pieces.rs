//! A profile's text cut at its table headers, so that its `[[register]]` tables can be
//! parsed a run at a time: `toml` builds a document as a tree of maps, about 45 bytes for
//! each byte of the file (166 MB for 65,536 registers), before a single register can be
//! checked; a run's tree is a few megabytes, dropped before the next run is parsed.
//!
//! The cut is made by toml's own lexer, so that it falls between the tokens the parser
//! reads, at the start of a header's line; it parses nothing, so it is a plan: its caller
//! checks that each run parses to `[[register]]` tables alone and the rest to no register,
//! and reads the file whole where they do not.

use std::ops::Range;
use toml_parser::lexer::{Lexer, Token, TokenKind};
use toml_parser::Source;

/// What a table header names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Header {
    /// `[[register]]`: the next register.
    Register,
    /// `[register.x]` or `[[register.x]]`: a table inside the register above.
    RegisterPart,
    /// Any other table.
    Other,
}

/// The most text one run of registers gathers before the next register starts another:
/// enough that parsing a run at a time costs no more than parsing the file whole.
const RUN: usize = 64 * 1024;

/// A profile's text in pieces.
#[derive(Debug, Default)]
pub(super) struct Pieces<'t> {
    /// The text outside the registers' tables (the keys before the first header,
    /// `[device]`, `[line]`, `[limits]`, ...), joined in the file's order.
    pub rest: String,
    /// Where the pieces of `rest` lie in the file: (offset in `rest`, offset in the file),
    /// ascending.
    pub rest_at: Vec<(usize, usize)>,
    /// The runs of `[[register]]` tables in the file's order: (offset in the file, text).
    pub runs: Vec<(usize, &'t str)>,
}

impl<'t> Pieces<'t> {
    /// `text` cut at its table headers: every `[[register]]` with the `[register.x]`
    /// tables that follow it into runs, everything else into the rest.
    pub fn new(text: &'t str) -> Pieces<'t> {
        let mut pieces = Pieces::default();
        let headers = headers(text);
        pieces.keep(text, 0..headers.first().map_or(text.len(), |(at, _)| *at));
        let mut run: Option<Range<usize>> = None;
        for (n, (at, header)) in headers.iter().enumerate() {
            let table = *at..headers.get(n + 1).map_or(text.len(), |(next, _)| *next);
            match (header, run.as_mut()) {
                (Header::Register, Some(open)) if open.len() < RUN => open.end = table.end,
                (Header::RegisterPart, Some(open)) => open.end = table.end,
                (Header::Register, _) => {
                    pieces.close(text, run.take());
                    run = Some(table);
                }
                _ => {
                    pieces.close(text, run.take());
                    pieces.keep(text, table);
                }
            }
        }
        pieces.close(text, run);
        pieces
    }

    /// How much text the pieces hold: the text's length, unless a piece was lost.
    pub fn len(&self) -> usize {
        self.rest.len() + self.runs.iter().map(|(_, run)| run.len()).sum::<usize>()
    }

    /// Adds `range` of `text` to the rest.
    fn keep(&mut self, text: &str, range: Range<usize>) {
        if let Some(piece) = text.get(range.clone()).filter(|p| !p.is_empty()) {
            let follows = self
                .rest_at
                .last()
                .is_some_and(|(from, to)| to + (self.rest.len() - from) == range.start);
            if !follows {
                self.rest_at.push((self.rest.len(), range.start));
            }
            self.rest.push_str(piece);
        }
    }

    /// Adds the run `range` of `text`, if any.
    fn close(&mut self, text: &'t str, range: Option<Range<usize>>) {
        if let Some(range) = range {
            if let Some(run) = text.get(range.clone()) {
                self.runs.push((range.start, run));
            }
        }
    }
}

/// The table headers of `text`, in order: where each header's line starts, and what it
/// names. A header is a line whose first token, outside the brackets of a value, is `[`.
fn headers(text: &str) -> Vec<(usize, Header)> {
    let mut out = Vec::new();
    let mut tokens = Source::new(text).lex();
    // Brackets and braces open in a value (a multi-line array or inline table).
    let mut depth = 0usize;
    // Where the line starts, until its first token that is not blank.
    let mut line_start = Some(0);
    while let Some(token) = tokens.next() {
        match (token.kind(), line_start) {
            (TokenKind::Newline, _) => {
                line_start = Some(token.span().end());
                continue;
            }
            (TokenKind::Whitespace, Some(_)) => continue,
            (TokenKind::LeftSquareBracket, Some(at)) if depth == 0 => {
                let (header, next_line) = header(text, token, &mut tokens);
                out.push((at, header));
                line_start = next_line;
                continue;
            }
            (TokenKind::LeftSquareBracket | TokenKind::LeftCurlyBracket, _) => depth += 1,
            (TokenKind::RightSquareBracket | TokenKind::RightCurlyBracket, _) => {
                depth = depth.saturating_sub(1);
            }
            _ => {}
        }
        line_start = None;
    }
    out
}

/// What the header opened by `open` names, its tokens taken from `tokens` to the end of its
/// line; and where the next line starts (None at the end of the text).
fn header(text: &str, open: Token, tokens: &mut Lexer<'_>) -> (Header, Option<usize>) {
    let mut words: Vec<(TokenKind, &str)> = Vec::new();
    let mut next_line = None;
    for token in tokens.by_ref() {
        let span = token.span();
        match token.kind() {
            TokenKind::Newline => {
                next_line = Some(span.end());
                break;
            }
            TokenKind::Whitespace | TokenKind::Comment => {}
            kind => {
                // `[[` only with nothing between the brackets.
                let apart = span.start() != open.span().end();
                if words.is_empty() && kind == TokenKind::LeftSquareBracket && apart {
                    words.push((TokenKind::Whitespace, ""));
                }
                words.push((kind, text.get(span.start()..span.end()).unwrap_or_default()));
            }
        }
    }
    use TokenKind::{Atom, Dot, LeftSquareBracket as Open, RightSquareBracket as Close};
    let header = match words.as_slice() {
        [(Atom, "register"), (Dot, _), ..] | [(Open, _), (Atom, "register"), (Dot, _), ..] => {
            Header::RegisterPart
        }
        [(Open, _), (Atom, "register"), (Close, _), (Close, _)] => Header::Register,
        _ => Header::Other,
    };
    (header, next_line)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn headers_are_found_outside_strings_comments_and_values() {
        let text = "x = 1\n[device]\nname = \"[[register]]\"\n  [[register]]  # one\n\
                    a = [\n[1],\n]\nb = \"\"\"\n[[register]]\n\"\"\"\nc = '''\n[x]'''\n\
                    # [[register]]\n[register.enum]\n[[ register ]]\n[[registers]]\n\
                    [register]\n['register']\n[ [register]]\n";
        let starts = |needle: &str| text.find(needle).unwrap_or(usize::MAX);
        assert_eq!(
            headers(text),
            vec![
                (starts("[device]"), Header::Other),
                (starts("  [[register]]  #"), Header::Register),
                (starts("[register.enum]"), Header::RegisterPart),
                (starts("[[ register ]]"), Header::Register),
                (starts("[[registers]]"), Header::Other),
                (starts("[register]\n"), Header::Other),
                (starts("['register']"), Header::Other),
                (starts("[ [register]]"), Header::Other),
            ]
        );
    }

    #[test]
    fn registers_gather_into_runs_and_the_rest_keeps_its_places() {
        let register = |n: usize| format!("[[register]]\nname = \"r{n}\"\naddress = {n}\n");
        let many: String = (0..4000).map(register).collect();
        let text = format!("# top\n[device]\nname = \"d\"\n{many}[limits]\nmax_read = 2\n");
        let pieces = Pieces::new(&text);
        assert!(pieces.runs.len() > 1, "{}", pieces.runs.len());
        let joined: String = pieces.runs.iter().map(|(_, run)| *run).collect();
        assert_eq!(joined, many);
        assert_eq!(pieces.len(), text.len());
        for (at, run) in &pieces.runs {
            assert!(run.starts_with("[[register]]"));
            assert_eq!(text.get(*at..*at + run.len()), Some(*run));
        }
        assert_eq!(
            pieces.rest,
            "# top\n[device]\nname = \"d\"\n[limits]\nmax_read = 2\n"
        );
        let limits = text.find("[limits]").unwrap_or_default();
        assert_eq!(pieces.rest_at, vec![(0, 0), (26, limits)]);
    }

    #[test]
    fn a_part_of_a_register_stays_with_it() {
        let text = "[[register]]\nname = \"a\"\n[register.enum]\n0 = \"off\"\n[device]\n\
                    [register.enum]\n";
        let pieces = Pieces::new(text);
        assert_eq!(
            pieces.runs,
            vec![(
                0,
                "[[register]]\nname = \"a\"\n[register.enum]\n0 = \"off\"\n"
            )]
        );
        // After another table, it is the rest's (and the file is then read whole).
        assert_eq!(pieces.rest, "[device]\n[register.enum]\n");
    }
}
