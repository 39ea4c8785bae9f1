//! The DMC program language, the subset a board-side watchdog needs: labels, variables,
//! arithmetic and comparisons, `IF`/`ELSE`/`ENDIF`, `JP`, `WT`, `EN`, and any controller command
//! (`MO`, `OF`, `XQ`, `HX`, ...) as a statement.
//!
//! A program arrives with `DL` (text up to `\` or Ctrl-Z) and is parsed then, so that a
//! malformed program is refused at download. Threads ([`Thread`]) run it: the [`Dmc`](super::Dmc)
//! gives each running thread a budget of [`LINES_PER_TICK`] statements per servo period, as a
//! real controller interleaves its threads, and `WT` parks a thread until its time comes.
//!
//! Expressions follow Galil's rule: operators are evaluated strictly left to right (no
//! precedence; use parentheses). Comparisons (`=`, `<>`, `<`, `>`, `<=`, `>=`) give 1 or 0, `&`
//! and `|` combine them. Operands: numbers, variables (a letter then up to seven letters or
//! digits), `TIME` (servo samples since power-up) and `_XXa` axis operands (`_TPA`, `_TSB`, ...).

use std::collections::HashMap;

use super::super::command::AXIS_LETTERS;

/// Statements a thread runs per servo period at most (a real DMC-40x0 runs a few per sample per
/// thread; a watchdog loop of eight statements then reacts within a sample or two).
pub const LINES_PER_TICK: usize = 8;

/// The longest variable name.
pub const MAX_NAME: usize = 8;

/// Galil error code of a program that does not parse (statement or label problems).
pub const CODE_BAD_PROGRAM: u16 = 1;
/// Galil error code for a jump or `XQ` to a label the program does not have.
pub const CODE_NO_LABEL: u16 = 3;

/// What a program reads and changes: the controller around it.
pub trait Machine {
    /// A variable's value (`None`: not defined yet).
    fn variable(&self, name: &str) -> Option<f64>;
    /// Defines or changes a variable; a Galil code when the variable table is full.
    fn set_variable(&mut self, name: &str, value: f64) -> Result<(), u16>;
    /// `TIME`: servo samples since power-up.
    fn time(&self) -> f64;
    /// An axis operand (`"TP"`, `"TS"`, ...) of axis `axis`, or `None` when unknown.
    fn operand(&self, name: &str, axis: usize) -> Option<f64>;
    /// Runs one controller command; a Galil code when it is rejected.
    fn command(&mut self, text: &str) -> Result<(), u16>;
}

#[derive(Clone, Debug, PartialEq)]
enum Token {
    Num(f64),
    Name(String),
    Operand(String, usize),
    Op(Op),
    Open,
    Close,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Op {
    Add,
    Sub,
    Mul,
    Div,
    Eq,
    Ne,
    Lt,
    Gt,
    Le,
    Ge,
    And,
    Or,
}

impl Op {
    fn apply(self, a: f64, b: f64) -> f64 {
        let truth = |c: bool| if c { 1.0 } else { 0.0 };
        match self {
            Op::Add => a + b,
            Op::Sub => a - b,
            Op::Mul => a * b,
            Op::Div => {
                if b == 0.0 {
                    0.0
                } else {
                    a / b
                }
            }
            Op::Eq => truth(a == b),
            Op::Ne => truth(a != b),
            Op::Lt => truth(a < b),
            Op::Gt => truth(a > b),
            Op::Le => truth(a <= b),
            Op::Ge => truth(a >= b),
            Op::And => truth(a != 0.0 && b != 0.0),
            Op::Or => truth(a != 0.0 || b != 0.0),
        }
    }
}

/// A parsed expression (tokens, evaluated left to right).
#[derive(Clone, Debug, PartialEq)]
pub struct Expr(Vec<Token>);

/// True for a valid variable name: a letter, then letters or digits, at most [`MAX_NAME`].
pub fn is_variable_name(s: &str) -> bool {
    let b = s.as_bytes();
    !b.is_empty()
        && b.len() <= MAX_NAME
        && b[0].is_ascii_alphabetic()
        && b.iter().all(u8::is_ascii_alphanumeric)
        && s != "TIME"
}

impl Expr {
    /// Parses an expression; a Galil code for bad syntax.
    pub fn parse(text: &str) -> Result<Expr, u16> {
        let bad = CODE_BAD_PROGRAM;
        let b = text.as_bytes();
        let mut tokens = Vec::new();
        let mut i = 0;
        while i < b.len() {
            let c = b[i];
            let two = |next: u8| b.get(i + 1) == Some(&next);
            let (token, len) = match c {
                b' ' => {
                    i += 1;
                    continue;
                }
                b'(' => (Token::Open, 1),
                b')' => (Token::Close, 1),
                b'+' => (Token::Op(Op::Add), 1),
                b'-' => (Token::Op(Op::Sub), 1),
                b'*' => (Token::Op(Op::Mul), 1),
                b'/' => (Token::Op(Op::Div), 1),
                b'&' => (Token::Op(Op::And), 1),
                b'|' => (Token::Op(Op::Or), 1),
                b'=' => (Token::Op(Op::Eq), 1),
                b'<' if two(b'>') => (Token::Op(Op::Ne), 2),
                b'<' if two(b'=') => (Token::Op(Op::Le), 2),
                b'>' if two(b'=') => (Token::Op(Op::Ge), 2),
                b'<' => (Token::Op(Op::Lt), 1),
                b'>' => (Token::Op(Op::Gt), 1),
                b'0'..=b'9' | b'.' => {
                    let len = b[i..]
                        .iter()
                        .take_while(|c| c.is_ascii_digit() || **c == b'.')
                        .count();
                    let v: f64 = text[i..i + len].parse().map_err(|_| bad)?;
                    (Token::Num(v), len)
                }
                b'_' => {
                    let name = text.get(i + 1..i + 3).ok_or(bad)?;
                    let letter = *b.get(i + 3).ok_or(bad)?;
                    let axis = AXIS_LETTERS
                        .iter()
                        .position(|&l| l as u8 == letter)
                        .ok_or(bad)?;
                    (Token::Operand(name.to_string(), axis), 4)
                }
                c if c.is_ascii_alphabetic() => {
                    let len = b[i..]
                        .iter()
                        .take_while(|c| c.is_ascii_alphanumeric())
                        .count();
                    let name = &text[i..i + len];
                    if name != "TIME" && !is_variable_name(name) {
                        return Err(bad);
                    }
                    (Token::Name(name.to_string()), len)
                }
                _ => return Err(bad),
            };
            tokens.push(token);
            i += len;
        }
        let e = Expr(tokens);
        // Check the shape once, so evaluation cannot fail on syntax later.
        e.check()?;
        Ok(e)
    }

    fn check(&self) -> Result<(), u16> {
        let mut pos = 0;
        self.shape(&mut pos, 0)?;
        if pos == self.0.len() {
            Ok(())
        } else {
            Err(CODE_BAD_PROGRAM)
        }
    }

    fn shape(&self, pos: &mut usize, depth: usize) -> Result<(), u16> {
        let bad = CODE_BAD_PROGRAM;
        if depth > 16 {
            return Err(bad);
        }
        self.shape_term(pos, depth)?;
        while let Some(Token::Op(_)) = self.0.get(*pos) {
            *pos += 1;
            self.shape_term(pos, depth)?;
        }
        Ok(())
    }

    fn shape_term(&self, pos: &mut usize, depth: usize) -> Result<(), u16> {
        let bad = CODE_BAD_PROGRAM;
        match self.0.get(*pos) {
            Some(Token::Num(_) | Token::Name(_) | Token::Operand(..)) => *pos += 1,
            Some(Token::Op(Op::Sub)) if depth <= 16 => {
                *pos += 1;
                self.shape_term(pos, depth + 1)?;
            }
            Some(Token::Open) => {
                *pos += 1;
                self.shape(pos, depth + 1)?;
                if self.0.get(*pos) != Some(&Token::Close) {
                    return Err(bad);
                }
                *pos += 1;
            }
            _ => return Err(bad),
        }
        Ok(())
    }

    /// The value; an undefined variable or unknown operand is a Galil code.
    pub fn eval(&self, m: &dyn Machine) -> Result<f64, u16> {
        let mut pos = 0;
        self.eval_from(&mut pos, m)
    }

    fn eval_from(&self, pos: &mut usize, m: &dyn Machine) -> Result<f64, u16> {
        let mut acc = self.term(pos, m)?;
        while let Some(Token::Op(op)) = self.0.get(*pos) {
            *pos += 1;
            let rhs = self.term(pos, m)?;
            acc = op.apply(acc, rhs);
        }
        Ok(acc)
    }

    fn term(&self, pos: &mut usize, m: &dyn Machine) -> Result<f64, u16> {
        let t = self.0.get(*pos).ok_or(CODE_BAD_PROGRAM)?;
        *pos += 1;
        match t {
            Token::Num(v) => Ok(*v),
            Token::Name(n) if n == "TIME" => Ok(m.time()),
            Token::Name(n) => m.variable(n).ok_or(CODE_BAD_PROGRAM),
            Token::Operand(n, a) => m.operand(n, *a).ok_or(CODE_BAD_PROGRAM),
            Token::Op(Op::Sub) => Ok(-self.term(pos, m)?),
            Token::Open => {
                let v = self.eval_from(pos, m)?;
                *pos += 1; // the closing parenthesis (checked at parse)
                Ok(v)
            }
            _ => Err(CODE_BAD_PROGRAM),
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
enum Statement {
    Label,
    Assign(String, Expr),
    /// Condition, index of the matching `ELSE` or `ENDIF`.
    If(Expr, usize),
    /// Index of the matching `ENDIF`.
    Else(usize),
    EndIf,
    Jump(String, Option<Expr>),
    /// Milliseconds.
    Wait(Expr),
    End,
    Command(String),
}

/// A downloaded program: statements and where each label is.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Program {
    statements: Vec<Statement>,
    labels: HashMap<String, usize>,
    text_len: usize,
}

/// One running thread.
#[derive(Clone, Debug, PartialEq)]
pub struct Thread {
    pc: usize,
    /// Parked by `WT` until this `TIME`.
    until: Option<f64>,
}

/// What a thread did in its slice.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Slice {
    /// Still running.
    Running,
    /// Ended (`EN`, or ran off the end).
    Ended,
    /// Stopped by an error with this Galil code.
    Error(u16),
}

/// Splits on `;` outside double quotes.
fn split_statements(line: &str) -> impl Iterator<Item = &str> {
    let mut parts = Vec::new();
    let mut start = 0;
    let mut quoted = false;
    for (i, c) in line.char_indices() {
        match c {
            '"' => quoted = !quoted,
            ';' if !quoted => {
                parts.push(&line[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    parts.push(&line[start..]);
    parts.into_iter()
}

/// A label as written (`#WDOG`), checked: `#`, a letter, then letters or digits, 2..=8 chars.
fn label(text: &str) -> Result<String, u16> {
    let t = text.trim();
    let name = t.strip_prefix('#').ok_or(CODE_BAD_PROGRAM)?;
    if name.is_empty()
        || name.len() > 7
        || !name.as_bytes()[0].is_ascii_alphabetic()
        || !name.bytes().all(|c| c.is_ascii_alphanumeric())
    {
        return Err(CODE_BAD_PROGRAM);
    }
    Ok(name.to_string())
}

impl Program {
    /// Parses downloaded text (lines end with CR, LF or both); a Galil code for anything it
    /// cannot run, so the download is refused as a whole.
    pub fn parse(text: &str) -> Result<Program, u16> {
        let bad = CODE_BAD_PROGRAM;
        let mut p = Program {
            text_len: text.len(),
            ..Program::default()
        };
        let mut open: Vec<usize> = Vec::new();
        for line in text.split(['\r', '\n']) {
            let line = line.trim();
            if line.is_empty() || line.starts_with('\'') || line.starts_with("REM") {
                continue;
            }
            if line.len() > super::super::command::MAX_LINE {
                return Err(bad);
            }
            for st in split_statements(line) {
                let st = st.trim();
                if st.is_empty() {
                    continue;
                }
                let index = p.statements.len();
                let parsed = if st.starts_with('#') {
                    let name = label(st)?;
                    if p.labels.insert(name, index).is_some() {
                        return Err(bad);
                    }
                    Statement::Label
                } else if let Some(cond) = st.strip_prefix("IF") {
                    open.push(index);
                    Statement::If(Expr::parse(cond)?, 0)
                } else if st == "ELSE" {
                    let at = *open.last().ok_or(bad)?;
                    match &mut p.statements[at] {
                        Statement::If(_, target) => *target = index,
                        _ => return Err(bad),
                    }
                    *open.last_mut().ok_or(bad)? = index;
                    Statement::Else(0)
                } else if st == "ENDIF" {
                    let at = open.pop().ok_or(bad)?;
                    match &mut p.statements[at] {
                        Statement::If(_, target) | Statement::Else(target) => *target = index,
                        _ => return Err(bad),
                    }
                    Statement::EndIf
                } else if let Some(rest) = st.strip_prefix("JP") {
                    let (to, cond) = match rest.split_once(',') {
                        Some((to, cond)) => (to, Some(Expr::parse(cond)?)),
                        None => (rest, None),
                    };
                    Statement::Jump(label(to)?, cond)
                } else if let Some(ms) = st.strip_prefix("WT") {
                    Statement::Wait(Expr::parse(ms)?)
                } else if st == "EN" {
                    Statement::End
                } else if let Some((name, value)) = st.split_once('=')
                    && is_variable_name(name.trim())
                    && !name.trim().bytes().take(2).all(|c| c.is_ascii_uppercase())
                {
                    Statement::Assign(name.trim().to_string(), Expr::parse(value)?)
                } else {
                    let b = st.as_bytes();
                    if b.len() < 2 || !b[0].is_ascii_uppercase() || !b[1].is_ascii_uppercase() {
                        return Err(bad);
                    }
                    Statement::Command(st.to_string())
                };
                p.statements.push(parsed);
            }
        }
        if !open.is_empty() {
            return Err(bad);
        }
        for s in &p.statements {
            if let Statement::Jump(to, _) = s
                && !p.labels.contains_key(to)
            {
                return Err(CODE_NO_LABEL);
            }
        }
        Ok(p)
    }

    /// Bytes of program text downloaded.
    pub fn text_len(&self) -> usize {
        self.text_len
    }

    /// A thread starting at `label` (without `#`), or a Galil code when there is no such label.
    pub fn start(&self, label: &str) -> Result<Thread, u16> {
        let pc = *self.labels.get(label).ok_or(CODE_NO_LABEL)?;
        Ok(Thread { pc, until: None })
    }

    /// A thread starting at the first statement (`XQ` without a label).
    pub fn first(&self) -> Thread {
        Thread { pc: 0, until: None }
    }

    /// Runs `thread` for at most `budget` statements (fewer when it waits or ends).
    pub fn run(&self, thread: &mut Thread, m: &mut dyn Machine, budget: usize) -> Slice {
        if let Some(until) = thread.until {
            if m.time() < until {
                return Slice::Running;
            }
            thread.until = None;
        }
        for _ in 0..budget {
            let Some(st) = self.statements.get(thread.pc) else {
                return Slice::Ended;
            };
            thread.pc += 1;
            let result: Result<(), u16> = match st {
                Statement::Label | Statement::EndIf => Ok(()),
                Statement::Assign(name, e) => e.eval(m).and_then(|v| m.set_variable(name, v)),
                Statement::If(cond, target) => cond.eval(m).map(|v| {
                    if v == 0.0 {
                        thread.pc = target + 1;
                    }
                }),
                Statement::Else(target) => {
                    thread.pc = target + 1;
                    Ok(())
                }
                Statement::Jump(to, cond) => {
                    let take = match cond {
                        Some(c) => c.eval(m).map(|v| v != 0.0),
                        None => Ok(true),
                    };
                    take.map(|t| {
                        if t {
                            // Labels were checked at download.
                            thread.pc = self.labels.get(to).copied().unwrap_or(usize::MAX);
                        }
                    })
                }
                Statement::Wait(ms) => match ms.eval(m) {
                    Ok(ms) => {
                        // TIME counts samples of about 1 ms (TM 1000); the caller's clock says.
                        thread.until = Some(m.time() + ms.max(0.0));
                        return Slice::Running;
                    }
                    Err(code) => Err(code),
                },
                Statement::End => return Slice::Ended,
                Statement::Command(text) => m.command(text),
            };
            if let Err(code) = result {
                return Slice::Error(code);
            }
        }
        Slice::Running
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Default)]
    struct Toy {
        vars: HashMap<String, f64>,
        time: f64,
        commands: Vec<String>,
    }

    impl Machine for Toy {
        fn variable(&self, name: &str) -> Option<f64> {
            self.vars.get(name).copied()
        }
        fn set_variable(&mut self, name: &str, value: f64) -> Result<(), u16> {
            self.vars.insert(name.into(), value);
            Ok(())
        }
        fn time(&self) -> f64 {
            self.time
        }
        fn operand(&self, name: &str, axis: usize) -> Option<f64> {
            (name == "TP").then_some(axis as f64 * 10.0)
        }
        fn command(&mut self, text: &str) -> Result<(), u16> {
            self.commands.push(text.into());
            Ok(())
        }
    }

    #[test]
    fn expressions_go_left_to_right() {
        let toy = Toy::default();
        let e = |s: &str| Expr::parse(s).unwrap().eval(&toy).unwrap();
        assert_eq!(e("1+2*3"), 9.0);
        assert_eq!(e("1+(2*3)"), 7.0);
        assert_eq!(e("-2+5"), 3.0);
        assert_eq!(e("(3>2)&(1<>1)"), 0.0);
        assert_eq!(e("(3>=3)|0"), 1.0);
        assert_eq!(e("_TPB+1"), 11.0);
        assert!(Expr::parse("1+").is_err());
        assert!(Expr::parse("(1").is_err());
        assert!(Expr::parse("a$").is_err());
        assert!(Expr::parse("").is_err());
        assert_eq!(Expr::parse("nothere").unwrap().eval(&toy), Err(1));
    }

    #[test]
    fn a_loop_with_if_and_wait() {
        let p =
            Program::parse("#A\rn=0\r#L\rIF (n<3)\rn=n+1\rELSE\rMO\rEN\rENDIF\rWT 2\rJP #L\rEN\r")
                .unwrap();
        let mut toy = Toy::default();
        let mut t = p.start("A").unwrap();
        let mut slices = 0;
        loop {
            match p.run(&mut t, &mut toy, LINES_PER_TICK) {
                Slice::Running => {}
                Slice::Ended => break,
                Slice::Error(c) => panic!("error {c}"),
            }
            toy.time += 1.0;
            slices += 1;
            assert!(slices < 100);
        }
        assert_eq!(toy.vars["n"], 3.0);
        assert_eq!(toy.commands, vec!["MO".to_string()]);
        // Three waits of 2 samples each.
        assert!(slices >= 6, "{slices}");
    }

    #[test]
    fn bad_programs_are_refused() {
        assert!(Program::parse("IF (1)\rMO\r").is_err());
        assert!(Program::parse("ENDIF\r").is_err());
        assert_eq!(Program::parse("JP #NOPE\r"), Err(CODE_NO_LABEL));
        assert!(Program::parse("#A\r#A\r").is_err());
        assert!(Program::parse("mo\r").is_err());
        assert!(Program::parse("#TOOLONGLABEL\r").is_err());
        assert!(Program::parse("' comment\r#A;x=1;EN\r").is_ok());
    }
}
