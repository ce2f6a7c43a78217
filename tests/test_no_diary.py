#!/usr/bin/env python3
"""test_no_diary.py SOURCE_DIR: the project's tracked text speaks of the product alone.

Every file `git ls-files` lists under SOURCE_DIR is read as text and searched for the words of a
work diary: who did what in which work period or round, under which issue number, on which day.
Such lines belong in commit messages at most, never in the code, its comments or its documents;
the measured figures stay, with their conditions and dates (docs/studies/). Prints every hit as
path:line: text and exits 1 if there is one, 0 if none. Needs git and a checkout: the suite runs
from a clone, so a missing git or a tree outside a checkout fails the test rather than passing it.
Python 3 standard library only.
"""
import re
import subprocess
import sys

# The diary's words. Case-insensitive; each pattern anchored on word boundaries so that product
# words that merely contain them do not match ("sessionStorage", "rounding", "round-trip",
# `round(x)`, a benchmark's "REPS rounds").
ORDINALS = ("first|second|third|fourth|fifth|sixth|seventh|eighth|ninth|tenth|eleventh|twelfth"
            "|\\d+(?:st|nd|rd|th)")
PATTERNS = [
    ("session", r"\bsessions?\b"),                       # a work session ("session 13")
    ("issue number", r"\bissues?\s*(?:#\s*)?\d+"),        # "issue 10", "issue #12", "issues 9"
    ("issue #", r"\bissue\s*#"),
    ("the issue", r"\b(?:the|this|that) issue(?:'s)?\b"),  # a tracker's item, not a product term
    ("helper", r"\bhelpers?\b"),                         # who did the work
    ("work period", r"\bwork[- ]periods?\b"),
    ("work round", r"\b(?:%s)[- ]rounds?\b" % ORDINALS),  # "the fifth round", "3rd round"
    ("work round", r"\brounds?\s+\d+\b"),                 # "round 5"
    ("work round", r"\b(?:earlier|previous|later|this|that|one|two|three|four|five|six|seven"
                   r"|eight|nine|ten) rounds? of (?:rules|tuning|work|candidates)\b"),
    ("work round", r"\b(?:in|of) (?:earlier|previous|later) rounds\b"),
    ("day", r"\byesterday\b"),
    ("day", r"\btoday(?:'s)?\b"),
    ("branch", r"\bthis branch\b"),
    ("person", r"\b(?:Claude|Anthropic|ChatGPT|OpenAI|Copilot|Gemini)\b"),
    ("people", r"\b(?:other|\d+|several|seven|eight) (?:engineers|developers|people)\b"),
]
COMPILED = [(name, re.compile(rx, re.IGNORECASE)) for name, rx in PATTERNS]

# Files that must hold such words: this test's own word list, and third-party lock files (npm's
# package-lock.json names packages such as "@babel/helper-...", which are not ours to word).
EXCLUDED_PATHS = {"tests/test_no_diary.py"}
EXCLUDED_NAMES = {"package-lock.json"}


def tracked_files(root):
    try:
        out = subprocess.run(["git", "-C", root, "ls-files", "-z"], check=True,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE).stdout
    except FileNotFoundError:
        sys.exit("test_no_diary: git is not installed; the test needs it to list the tracked files")
    except subprocess.CalledProcessError as e:
        sys.exit("test_no_diary: %s is not a git checkout (git ls-files: %s)"
                 % (root, e.stderr.decode(errors="replace").strip()))
    files = [f for f in out.decode().split("\0") if f]
    if not files:
        sys.exit("test_no_diary: git ls-files lists no files under %s" % root)
    return files


def hits(root, path):
    try:
        with open("%s/%s" % (root, path), "rb") as f:
            data = f.read()
    except (FileNotFoundError, IsADirectoryError):
        return  # deleted in the working tree, or a submodule
    if b"\0" in data:
        return  # binary (images, FITS)
    text = data.decode("utf-8", errors="replace")
    for n, line in enumerate(text.splitlines(), 1):
        for name, rx in COMPILED:
            m = rx.search(line)
            if m:
                yield n, name, m.group(0), line.strip()
                break


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: test_no_diary.py SOURCE_DIR")
    root = sys.argv[1]
    files = tracked_files(root)
    found = 0
    for path in files:
        if path in EXCLUDED_PATHS or path.rsplit("/", 1)[-1] in EXCLUDED_NAMES:
            continue
        for n, name, word, line in hits(root, path):
            found += 1
            print("%s:%d: %s (%r): %s" % (path, n, name, word, line[:160]))
    if found:
        print("test_no_diary: %d diary line(s) in %d tracked files: say what the product does, "
              "not who did what when" % (found, len(files)))
        return 1
    print("test_no_diary: %d tracked files, no diary words" % len(files))
    return 0


if __name__ == "__main__":
    sys.exit(main())
