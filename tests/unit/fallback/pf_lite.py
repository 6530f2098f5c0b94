#!/usr/bin/env python3
"""The project's pFUnit tests without pFUnit: turns a .pf suite into Fortran that the fallback
module tests/unit/fallback/funit.f90 runs, plus a driver program (tests/README.md, Unit tests).

It handles exactly the part of pFUnit's syntax the project's tests use, and refuses the rest:
  @test              before `subroutine NAME()`: a test
  @test(cases = [1, 2, 3])
                     before `subroutine NAME(this)`: a test run once per case (integer literals,
                     as pFUnit reads them), with `this` made by the @testCase constructor from
                     the @testParameter constructor's parameter of the case; named
                     NAME[the parameter's toString]
  @testParameter(constructor=F)   before the parameter type (extends AbstractTestParameter)
  @testCase(constructor=G)        before the test-case type (extends ParameterizedTestCase)
  @before            before `subroutine NAME()`: called before every test of the suite
  @assertTrue(...)   \\
  @assertFalse(...)   > one line each: `call assertX(..., location=...)`, then the test returns
  @assertEqual(...)  /  if it failed (as pFUnit's generated code does)

The driver runs every test, or the tests named on its command line (`--list` names them), and
prints a line `ok - SUITE.TEST` or `not ok - SUITE.TEST` per test (after a failure's report) and
pFUnit's kind of summary: `OK (N tests)` or `FAILURES!!! Tests run: N, Failures: F`; its exit
status is 1 if a test failed.

usage: pf_lite.py SUITE.pf OUTPUT_DIR   (writes OUTPUT_DIR/SUITE.F90 and OUTPUT_DIR/SUITE_driver.F90)
"""
import re
import sys
from pathlib import Path

ASSERTIONS = ("assertTrue", "assertFalse", "assertEqual")
SUBROUTINE = re.compile(r"^\s*subroutine\s+(\w+)\s*\(\s*(this)?\s*\)", re.IGNORECASE)
TYPE = re.compile(r"^\s*type\s*,\s*extends\s*\(\s*\w+\s*\)\s*::\s*(\w+)", re.IGNORECASE)
CASES = re.compile(r"^@test\s*\(\s*cases\s*=\s*\[([^\]]*)\]\s*\)$", re.IGNORECASE)
CONSTRUCTOR = re.compile(r"^@(testParameter|testCase)\s*\(\s*constructor\s*=\s*(\w+)\s*\)$", re.IGNORECASE)
SUBSET = ("@test, @test(cases = [...]), @testParameter, @testCase, @before, @assertTrue, @assertFalse, "
          "@assertEqual")
DRIVER = Path(__file__).with_name("driver_template.F90")


class SyntaxProblem(Exception):
    """A line of the .pf file outside the subset this tool handles."""


def closing_parenthesis(text, start):
    """Index of the ')' that closes the '(' at `start`, skipping quoted texts."""
    depth, quote = 0, None
    for index in range(start, len(text)):
        char = text[index]
        if quote:
            if char == quote:
                quote = None
        elif char in "'\"":
            quote = char
        elif char == "(":
            depth += 1
        elif char == ")":
            depth -= 1
            if depth == 0:
                return index
    return -1


def assertion(line, name, number):
    """The Fortran of one @assert line, or None if the line is none."""
    match = re.match(r"^(\s*)@(\w+)(.*)$", line)
    if not match:
        return None
    indent, directive, rest = match.groups()
    if directive not in ASSERTIONS:
        raise SyntaxProblem(f"{name}:{number}: @{directive} is not in the fallback's subset of pFUnit ({SUBSET})")
    end = closing_parenthesis(rest, rest.find("("))
    if not rest.lstrip().startswith("(") or end < 0 or rest[end + 1:].strip():
        raise SyntaxProblem(f"{name}:{number}: @{directive}(...) must be one whole line")
    arguments = rest[rest.find("(") + 1:end]
    return [f"{indent}call {directive}({arguments}, location=SourceLocation('{name}', {number}))",
            f"{indent}if (anyExceptions()) return"]


def translate(source, name):
    """(Fortran text, suite) of a .pf text. suite: module, tests [(name, cases or None)], before,
    and the parameterized tests' case type, case constructor and parameter constructor."""
    out = []
    suite = {"module": None, "tests": [], "before": None, "case_type": None, "case": None, "parameter": None}
    pending = pending_type = None
    for number, line in enumerate(source.split("\n"), start=1):
        stripped = line.strip()
        match = re.match(r"^module\s+(\w+)\s*$", stripped, re.IGNORECASE)
        if match and suite["module"] is None:
            suite["module"] = match.group(1)
        if pending:
            match = SUBROUTINE.match(line)
            if match:
                if pending[0] == "@before":
                    suite["before"] = match.group(1)
                elif (pending[1] is None) != (match.group(2) is None):
                    raise SyntaxProblem(f"{name}:{number}: a test with cases takes `this`, a test without none")
                else:
                    suite["tests"].append((match.group(1), pending[1]))
                pending = None
            elif stripped and not stripped.startswith("!"):
                raise SyntaxProblem(f"{name}:{number}: {pending[0]} must stand right before 'subroutine NAME()'")
        if pending_type:
            match = TYPE.match(line)
            if match:
                if pending_type == "testcase":
                    suite["case_type"] = match.group(1)
                pending_type = None
        if stripped.lower() in ("@test", "@test()", "@before"):
            pending = ("@before" if stripped.lower() == "@before" else "@test", None)
            continue
        match = CASES.match(stripped)
        if match:
            cases = [case.strip() for case in match.group(1).split(",") if case.strip()]
            if not cases or not all(re.fullmatch(r"[+-]?\d+", case) for case in cases):
                raise SyntaxProblem(f"{name}:{number}: cases must be integer literals, as pFUnit reads them")
            pending = ("@test", cases)
            continue
        match = CONSTRUCTOR.match(stripped)
        if match:
            pending_type = match.group(1).lower()
            suite["case" if pending_type == "testcase" else "parameter"] = match.group(2)
            continue
        translated = assertion(line, name, number)
        out.extend(translated if translated else [line])
    if suite["module"] is None:
        raise SyntaxProblem(f"{name}: no 'module NAME' line")
    if not suite["tests"]:
        raise SyntaxProblem(f"{name}: no @test")
    if any(cases for _, cases in suite["tests"]) and not (suite["case_type"] and suite["case"] and suite["parameter"]):
        raise SyntaxProblem(f"{name}: tests with cases need @testParameter(constructor=...) and "
                            "@testCase(constructor=...) types")
    return "\n".join(out), suite


def driver(suite):
    """The program that runs the suite's tests, each case of a parameterized test on its own
    (tests/unit/fallback/driver_template.F90 filled in)."""
    runs = []          # (test, the statements that run it, its case or None)
    for test, cases in suite["tests"]:
        if cases is None:
            runs.append((test, f"call {test}()", None))
        else:
            for case in cases:
                runs.append((test, f"this = {suite['case']}({suite['parameter']}({case}))\n"
                                   f"      call {test}(this)", case))
    used = {test for test, _ in suite["tests"]}
    if suite["before"]:
        used.add(suite["before"])
    if suite["case_type"]:
        used |= {suite["case_type"], suite["case"], suite["parameter"]}
    names = "\n".join(f"    case ({k})\n      text = '{test}'"
                      + (f"//'['//text_of({suite['parameter']}({case}))//']'" if case is not None else "")
                      for k, (test, _, case) in enumerate(runs, start=1))
    text_of = ""
    if suite["case_type"]:
        text_of = (f"\n  ! A parameter's name (its toString).\n  function text_of(parameter) result(text)\n"
                   f"    class(AbstractTestParameter), intent(in) :: parameter\n"
                   f"    character(len=:), allocatable :: text\n\n    text = parameter%toString()\n"
                   f"  end function text_of\n")
    fills = {
        "MODULE": suite["module"],
        "USES": ", ".join(sorted(used)),
        "COUNT": str(len(runs)),
        "NAMES": names,
        "CASES": "\n".join(f"    case ({k})\n      {statements}" for k, (_, statements, _) in enumerate(runs, start=1)),
        "BEFORE": f"\n    call {suite['before']}()" if suite["before"] else "",
        "THIS": f"\n    type({suite['case_type']}) :: this" if suite["case_type"] else "",
        "FUNIT_USES": ", AbstractTestParameter" if suite["case_type"] else "",
        "TEXT_OF": text_of,
    }
    text = DRIVER.read_text()
    for key, value in fills.items():
        text = text.replace(f"@{key}@", value)
    return text


def main(argv):
    if len(argv) != 3:
        print(__doc__.split("\n\n")[-1], file=sys.stderr)
        return 2
    source, output = Path(argv[1]), Path(argv[2])
    try:
        text, suite = translate(source.read_text(), source.name)
    except SyntaxProblem as problem:
        print(f"pf_lite.py: {problem}", file=sys.stderr)
        return 1
    output.mkdir(parents=True, exist_ok=True)
    (output / f"{source.stem}.F90").write_text(f"! Generated by tests/unit/fallback/pf_lite.py from {source}.\n"
                                                + text)
    (output / f"{source.stem}_driver.F90").write_text(driver(suite))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
