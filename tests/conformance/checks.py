"""The conformance scripts' shared tally: one line per check, and the
closing line `NAME: N passed, M failed` that run.sh adds up (NAME:
lower-case letters, digits and spaces)."""


class Checks:
    def __init__(self):
        self.passed = 0
        self.failed = 0

    def check(self, name, ok, detail=""):
        """Counts and prints one check; returns whether it passed."""
        ok = bool(ok)
        if ok:
            self.passed += 1
        else:
            self.failed += 1
        print(f"{'ok  ' if ok else 'FAIL'} {name}" + (f": {detail}" if detail else ""),
              flush=True)
        return ok

    def close(self, name):
        """Prints the closing line; the exit code: 1 on any failure."""
        print(f"{name}: {self.passed} passed, {self.failed} failed")
        return 1 if self.failed else 0
