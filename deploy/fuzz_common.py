"""What the release checks fuzz_runs.py and fuzz_options.py share: the
sanitizers' settings and how one call's end is judged."""
import os

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def sanitizer_env():
    """The environment with the sanitizers' options set (as deploy/sanitize.sh)
    where the caller has not set them: leaks detected less deploy/lsan.supp,
    UBSan halting with a stack trace."""
    env = dict(os.environ)
    env.setdefault("ASAN_OPTIONS", "detect_leaks=1")
    env.setdefault("LSAN_OPTIONS", f"suppressions={ROOT}/deploy/lsan.supp:print_suppressions=0")
    env.setdefault("UBSAN_OPTIONS", "print_stacktrace=1:halt_on_error=1")
    return env


def failure(rc, err):
    """'TIMEOUT' (rc None: the call was stopped), 'SANITIZER', 'SIGNAL', or None
    when the call ended by itself with an exit status."""
    if rc is None:
        return "TIMEOUT"
    if "Sanitizer" in err or "runtime error" in err:
        return "SANITIZER"
    if rc < 0:
        return "SIGNAL"
    return None
