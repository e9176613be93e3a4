#!/usr/bin/env python3
"""check_quoted_numbers.py [--root DIR] [TABLE]: numbers the specs quote from code constants.

A spec in proto/ or docs/ that says "the black box holds 256 cycles" copies a number from the
code (Cycle::kBlackBoxCycles); when the constant changes the sentence goes stale without a word.
TABLE (TOML, default tests/docs/quoted_numbers.toml beside this script) lists such quotes, each
as a [[quote]] with:

  doc      the spec, relative to --root
  pattern  a Python regular expression whose first group is the quoted number; it must match the
           spec at least once, and every match must agree with the constant
  header   the header that defines the constant, relative to --root
  constant the constant's name (read as `name = value` or `name{value}` up to `;` or `}`, the value
           an integer or floating-point expression), or a regular expression with one group
           when the number is not a named constant (a template argument)
  scale    optional: the constant is the quoted number times this (KiB quoted, bytes in code)

Prints one line per quote; exit 0 when all agree, 1 otherwise (a quote missing from its spec or
a constant missing from its header fails too).
"""
import argparse
import ast
import operator
import os
import re
import sys
import tomllib

OPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
       ast.Div: operator.truediv, ast.LShift: operator.lshift, ast.RShift: operator.rshift,
       ast.USub: operator.neg, ast.UAdd: operator.pos}


def evaluate(expr):
    """The value of a C++ constant expression of literals (1'000, 0x18u, 256 * 1024, 1u << 14)."""
    text = expr.replace("'", "")
    text = re.sub(r"\b(0[xX][0-9a-fA-F]+|\d+\.?\d*(?:[eE][-+]?\d+)?)[uUlLfF]+\b", r"\1", text)
    text = re.sub(r"static_cast<[^>]*>", "", text)

    def walk(node):
        if isinstance(node, ast.Expression):
            return walk(node.body)
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
            return node.value
        if isinstance(node, ast.BinOp) and type(node.op) in OPS:
            return OPS[type(node.op)](walk(node.left), walk(node.right))
        if isinstance(node, ast.UnaryOp) and type(node.op) in OPS:
            return OPS[type(node.op)](walk(node.operand))
        raise ValueError(f"not a constant expression of literals: {expr.strip()}")
    return walk(ast.parse(text.strip(), mode="eval"))


def constant_value(header_text, constant):
    """The constant's value in the header, or raise ValueError."""
    if "(" in constant:
        found = re.findall(constant, header_text)
    else:
        found = re.findall(r"\b%s\s*(?:=\s*([^;{}]+?)\s*;|\{([^;{}]+)\})" % re.escape(constant),
                           header_text)
        found = [a or b for a, b in found]
    if not found:
        raise ValueError(f"{constant} is not defined there")
    values = {evaluate(f) for f in found}
    if len(values) != 1:
        raise ValueError(f"{constant} has several values: {sorted(values)}")
    return values.pop()


def check(root, quote):
    """(ok, message) for one [[quote]]."""
    doc, header = quote["doc"], quote["header"]
    what = f"{doc} /{quote['pattern']}/ against {header} {quote['constant']}"
    try:
        with open(os.path.join(root, header), encoding="utf-8") as f:
            value = constant_value(f.read(), quote["constant"])
    except (OSError, ValueError, SyntaxError) as e:
        return False, f"{what}: {e}"
    try:
        with open(os.path.join(root, doc), encoding="utf-8") as f:
            text = f.read()
    except OSError as e:
        return False, f"{what}: {e}"
    matches = list(re.finditer(quote["pattern"], text))
    if not matches:
        return False, f"{what}: the spec no longer says it (pattern not found)"
    scale = quote.get("scale", 1)
    for m in matches:
        quoted = evaluate(m.group(1))
        if abs(quoted * scale - value) > 1e-12 * max(1.0, abs(value)):
            line = text.count("\n", 0, m.start()) + 1
            return False, (f"{doc}:{line}: quotes {m.group(1)}"
                           f"{f' (× {scale})' if scale != 1 else ''}, but {header} has "
                           f"{quote['constant']} = {value:g}")
    return True, f"{what}: {value:g} ({len(matches)}×)"


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--root", default=os.path.join(here, "..", ".."))
    ap.add_argument("table", nargs="?", default=os.path.join(here, "quoted_numbers.toml"))
    args = ap.parse_args()
    with open(args.table, "rb") as f:
        quotes = tomllib.load(f).get("quote", [])
    if not quotes:
        print(f"check_quoted_numbers: {args.table} lists no [[quote]]")
        return 1
    failed = 0
    for q in quotes:
        ok, message = check(os.path.abspath(args.root), q)
        print(f"{'ok  ' if ok else 'FAIL'} {message}")
        failed += not ok
    print(f"check_quoted_numbers: {len(quotes)} quotes, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
