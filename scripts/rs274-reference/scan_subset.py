#!/usr/bin/env python3
"""Which RS274-NGC programs stay inside the ISO subset cncd runs, and where the others leave it.

A textual scanner, written apart from the Rust interpreter on purpose: it decides from the
program text alone, so a wrong refusal in the kernel cannot hide behind the same wrong rule
here. The refusal is static: the first word outside the subset in text order wherever it
stands (in a subroutine that is never called too), up to the program's end (M2/M30 outside a
subroutine definition, or the closing `%`).

Usage: scan_subset.py FILE...   prints `<name> <line> <word> [code]` for each refused file.
The code column is present when the kernel's diagnostic code is not `iso_unsupported`:
another code, or `error` where any error code will do (text that is not RS274-NGC at all).
"""

import re
import sys

# Letters of words the subset reads (LinuxCNC reads A B C U V W E $ @ ^ too).
LETTERS = set("XYZIJKRPQLDHFSTNGM")

G_SUPPORTED = {
    "0", "1", "2", "3", "4", "10", "17", "18", "19", "20", "21", "40", "41", "42", "43", "49",
    "38.2", "38.3", "38.4", "38.5", "53", "54", "55", "56", "57", "58", "59", "59.1", "59.2", "59.3", "61", "61.1", "64",
    "73", "80", "81", "82", "83", "85", "89", "90", "91", "90.1", "91.1", "92", "92.1",
    "93", "94", "95", "97", "98", "99",
}
M_SUPPORTED = {"0", "1", "2", "3", "4", "5", "6", "7", "8", "9", "30"}
# G10 forms the subset runs: L2 and L20 (work offsets); tool-table writes are not in it.
G10_L_SUPPORTED = {"2", "20"}

FUNCS = ("ABS", "ACOS", "ASIN", "ATAN", "COS", "EXISTS", "EXP", "FIX", "FUP", "LN", "ROUND",
         "SIN", "SQRT", "TAN")
OKEYWORDS = ("ENDSUB", "SUB", "CALL", "RETURN", "DO", "ENDWHILE", "WHILE", "ELSEIF", "ELSE",
             "ENDIF", "IF", "ENDREPEAT", "REPEAT", "BREAK", "CONTINUE")

NUMBER = re.compile(r"[0-9]+\.?[0-9]*|\.[0-9]+")


class Refused(Exception):
    def __init__(self, word, code=None):
        super().__init__(word)
        self.word = word
        self.code = code


def strip_comments(line):
    """The line without `( … )` comments and `;` remarks, without spaces, upper case."""
    out = []
    depth = False
    for ch in line:
        if depth:
            if ch == ")":
                depth = False
            continue
        if ch == "(":
            depth = True
            continue
        if ch == ";":
            break
        out.append(ch)
    return "".join(out).replace(" ", "").replace("\t", "").replace("\r", "").upper()


def bracket_end(s, i):
    """Index just past the `]` that closes the `[` at `s[i]`."""
    assert s[i] == "["
    depth = 0
    for k in range(i, len(s)):
        if s[k] == "[":
            depth += 1
        elif s[k] == "]":
            depth -= 1
            if depth == 0:
                return k + 1
    raise Refused(s[i:], "expression_syntax")


def param_end(s, i):
    """Index past a parameter reference starting with `#` at `s[i]`."""
    assert s[i] == "#"
    i += 1
    if i < len(s) and s[i] == "<":
        k = s.find(">", i)
        if k < 0:
            raise Refused(s[i - 1:], "expression_syntax")
        return k + 1
    if i < len(s) and s[i] == "[":
        return bracket_end(s, i)
    if i < len(s) and s[i] == "#":
        return param_end(s, i)
    m = NUMBER.match(s, i)
    if not m:
        raise Refused(s[i - 1:], "expression_syntax")
    return m.end()


def value_end(s, i):
    """Index past the real value (number, [expression], #parameter, FUNC[...]) at `s[i]`."""
    while i < len(s) and s[i] in "+-":
        i += 1
    if i >= len(s):
        raise Refused(s, "expression_syntax")
    if s[i] == "[":
        return bracket_end(s, i)
    if s[i] == "#":
        return param_end(s, i)
    m = NUMBER.match(s, i)
    if m:
        return m.end()
    for f in FUNCS:
        if s.startswith(f + "[", i):
            k = bracket_end(s, i + len(f))
            if f == "ATAN" and s.startswith("/[", k):
                k = bracket_end(s, k + 1)
            return k
    raise Refused(s[i:i + 8], "expression_syntax")


def code_text(v):
    """`G01` → `1`, `G59.10` → `59.1`: a G or M number as the subset's tables write it."""
    if "." in v:
        a, b = v.split(".", 1)
        b = b.rstrip("0")
        return str(int(a or "0")) + ("." + b if b else "")
    return str(int(v))


def words_of(s):
    """(letter, value text, literal or None) of each word of a stripped line, in order;
    assignments `#…=value` are skipped."""
    out = []
    i = 0
    while i < len(s):
        ch = s[i]
        if ch == "#":
            k = param_end(s, i)
            if k < len(s) and s[k] == "=":
                i = value_end(s, k + 1)
                continue
            raise Refused(s[i:k], "expression_syntax")
        if ch.isalpha() or ch in "@^$":
            k = value_end(s, i + 1) if i + 1 < len(s) else i + 1
            text = s[i + 1:k]
            lit = text if NUMBER.fullmatch(text.lstrip("+-")) else None
            out.append((ch, text, lit))
            i = k
            continue
        raise Refused(s[i:i + 8], "expression_syntax")
    return out


OWORD = re.compile(r"O(<[^>]*>|[0-9]+)([A-Z]*)")


def scan(text):
    """(line, word, code) of the first refusal, or None when the program is in the subset."""
    lines = text.split("\n")
    subs = set()
    for line in lines:
        m = OWORD.match(strip_comments(line).lstrip("/"))
        if m and m.group(2) == "SUB":
            subs.add(m.group(1))
    in_sub = None
    percent = 0
    motion = None
    for no, raw in enumerate(lines, start=1):
        s = strip_comments(raw)
        if s.startswith("/"):
            s = s[1:]
        if not s:
            continue
        if s == "%":
            percent += 1
            if percent == 2:
                return None
            continue
        try:
            m = OWORD.match(s)
            if m:
                label, kw = m.group(1), m.group(2)
                if kw not in OKEYWORDS:
                    # Not RS274-NGC at all (LinuxCNC stops there too): any error will do.
                    raise Refused(kw or "O" + label, "error")
                if kw == "SUB":
                    in_sub = label
                elif kw == "ENDSUB" and label == in_sub:
                    in_sub = None
                elif kw == "CALL" and label not in subs:
                    raise Refused("O" + label, "subroutine_unknown")
                continue
            ws = words_of(s)
            letters = {w[0]: w for w in ws}
            ends = False
            for letter, text_v, lit in ws:
                word = letter + text_v
                if letter not in LETTERS:
                    raise Refused(word)
                if letter in "GM" and lit is None:
                    # A computed G or M code cannot be checked before it runs.
                    raise Refused(word)
                if letter == "G":
                    g = code_text(lit)
                    if g not in G_SUPPORTED:
                        raise Refused("G" + g)
                    if g in ("0", "1", "2", "3", "73", "80", "81", "82", "83", "85", "89"):
                        motion = g
                    if g == "10":
                        L = letters.get("L")
                        if not L or L[2] is None or code_text(L[2]) not in G10_L_SUPPORTED:
                            raise Refused("G10")
                        if "R" in letters:
                            # G10 L2 R: rotation of the coordinate system.
                            raise Refused("G10")
                if letter == "M":
                    mc = code_text(lit)
                    if mc not in M_SUPPORTED:
                        raise Refused("M" + mc)
                    if mc in ("2", "30") and in_sub is None:
                        ends = True
            if motion in ("2", "3") and "P" in letters and not any(
                w[0] == "G" and w[2] is not None and code_text(w[2]) in ("4", "10", "64")
                for w in ws
            ):
                p = letters["P"]
                if p[2] is not None and float(p[2]) != 1.0:
                    raise Refused("P" + p[1], "arc_radius_form")
            if ends:
                return None
        except Refused as r:
            return (no, r.word, r.code)
    return None


# (program, expected scan) pairs: the rules above on the cases that are easy to get wrong.
SELF_TEST = [
    ("G1 X[#1+2] Y#<_x> Z-#3 F[ABS[-100]]\nG0 X ATAN[1]/[2] Y SIN[30]\n", None),
    ("G01 M06 T1 ; G28 in a remark\n(G28 in a comment) G0 X1\n", None),
    ("N10 G0 X1\nN20 G28\n", (2, "G28", None)),
    ("G0 x1 a10\n", (1, "A10", None)),
    ("G0 X1 W[#1]\n", (1, "W[#1]", None)),
    ("G10 L1 P1 Z2\n", (1, "G10", None)),
    ("G10 L2 P1 X1 R30\n", (1, "G10", None)),
    ("G10 L20 P2 X1\nG92.1\nG92.2\n", (3, "G92.2", None)),
    ("G2 X1 Y0 I0.5 P2\n", (1, "P2", "arc_radius_form")),
    ("G2 X1 Y0 I0.5 P1\nG4 P2\nG64 P0.1 Q0.05\nG82 R1 Z-1 P2\n", None),
    ("o<x> call\n", (1, "O<X>", "subroutine_unknown")),
    ("o<x> sub\nG33 Z-1 K1\no<x> endsub\nM2\n", (2, "G33", None)),
    ("G0 X1\nM30\nG28\n", None),
    ("%\nG0 X1\n%\nG28\n", None),
    ("G59.1 G59.3\nG59.4\n", (2, "G59.4", None)),
    ("/G0 X1\nG91.1 G90.1 G61.1 G43 H1 G49\nM66 P0\n", (3, "M66", None)),
]


def self_test():
    for text, want in SELF_TEST:
        got = scan(text)
        if got != want:
            sys.exit(f"scan_subset self-test: {text!r} gives {got}, expected {want}")


def main(paths):
    self_test()
    for p in paths:
        with open(p, encoding="utf-8", errors="replace") as f:
            r = scan(f.read())
        if r:
            name = p.rsplit("/", 1)[-1].rsplit(".", 1)[0]
            line, word, code = r
            print(f"{name} {line} {word}" + (f" {code}" if code else ""))


if __name__ == "__main__":
    main(sys.argv[1:])
