"""DDS domains claimed for one test at a time across every test process of the machine: suites
run in parallel (ctest --parallel), and two tests on one domain see each other's participants
(a second bridge importing the same action, goals answered by another test's server)."""
from __future__ import annotations

import contextlib
import fcntl
import os
import random
import tempfile
from typing import Iterator

# Cyclone DDS takes domain ids 0-232; 0 is the default, which anything else on the machine uses.
DOMAINS = range(1, 230)
CLAIMS = os.path.join(tempfile.gettempdir(), "horus-test-dds-domains")


@contextlib.contextmanager
def claimed_domain() -> Iterator[int]:
    """A domain no other test holds, held until the block ends (or its process dies: the
    claim is an flock, which the kernel drops with the process)."""
    os.makedirs(CLAIMS, exist_ok=True)
    for domain in random.sample(DOMAINS, len(DOMAINS)):
        claim = os.open(os.path.join(CLAIMS, str(domain)), os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(claim, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(claim)
            continue
        try:
            yield domain
        finally:
            os.close(claim)
        return
    raise RuntimeError(f"every DDS domain of {DOMAINS} is held by another test")
