"""JUnit XML for ``--junit FILE``: the de-facto format CI systems show as test results.

One ``<testsuite>`` per command run inside ``<testsuites>``; one ``<testcase>`` per checked item
(a USD file for ``validate``, a scene for ``check-renders``) with ``<failure>`` (a finding, a
differing render) or ``<error>`` (an input that could not be checked) children. The elements and
attributes are those of the JUnit schema that Jenkins, GitLab and GitHub reporters read
(``testsuites/testsuite[@name,@tests,@failures,@errors,@time]/testcase[@classname,@name,@time]``).
"""

from __future__ import annotations

import datetime as _dt
import os
import socket
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field


@dataclass
class Problem:
    """A ``<failure>`` or ``<error>`` of a test case: a one-line ``message`` and detail ``text``."""

    message: str
    text: str = ""
    kind: str = "failure"  # or "error"


@dataclass
class Case:
    """One ``<testcase>``: ``classname`` groups cases (``pavonine.validate``), ``name`` is the item."""

    classname: str
    name: str
    seconds: float = 0.0
    problems: list[Problem] = field(default_factory=list)
    output: str = ""


def junit_xml(suite: str, cases: list[Case]) -> bytes:
    """The JUnit XML document (UTF-8 bytes) of one suite."""
    failures = sum(1 for c in cases if any(p.kind == "failure" for p in c.problems))
    errors = sum(1 for c in cases if any(p.kind == "error" for p in c.problems))
    root = ET.Element(
        "testsuites",
        name="pavonine",
        tests=str(len(cases)),
        failures=str(failures),
        errors=str(errors),
        time=f"{sum(c.seconds for c in cases):.3f}",
    )
    element = ET.SubElement(
        root,
        "testsuite",
        name=suite,
        tests=str(len(cases)),
        failures=str(failures),
        errors=str(errors),
        skipped="0",
        time=f"{sum(c.seconds for c in cases):.3f}",
        timestamp=_dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        hostname=socket.gethostname(),
    )
    for case in cases:
        node = ET.SubElement(
            element,
            "testcase",
            classname=case.classname,
            name=case.name,
            time=f"{case.seconds:.3f}",
        )
        for problem in case.problems:
            child = ET.SubElement(node, problem.kind, message=problem.message, type=problem.kind)
            child.text = problem.text or problem.message
        if case.output:
            ET.SubElement(node, "system-out").text = case.output
    ET.indent(root)
    return ET.tostring(root, encoding="utf-8", xml_declaration=True) + b"\n"


def write_junit(path: str | os.PathLike, suite: str, cases: list[Case]) -> None:
    """Write :func:`junit_xml` to ``path`` atomically."""
    from pavonine.base.commit import atomic_path

    with atomic_path(path) as tmp:
        tmp.write_bytes(junit_xml(suite, cases))
