"""Fuzzing the HTTP API of ``tml serve`` from its own OpenAPI document (schemathesis).

Every operation is called with inputs generated from the document, valid and not, and
every answer must be no server error, conform to the document (status, content type,
schema, headers) and never hold a traceback; a request the document allows may be
refused (422) by the language or the verifier. The service flies fake vehicles whose time stands
still, so a run the fuzzer starts stays in flight until the module ends.
"""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from collections import Counter
from pathlib import Path

import pytest
import schemathesis
from hypothesis import HealthCheck, settings
from schemathesis.specs.openapi.checks import positive_data_acceptance
from serving import ROOT, SHORT, FakeHangar

from tml.serve.api import create_app
from tml.serve.service import Service, ServiceOptions
from tml.serve.storage import Storage, database_url

EXAMPLES = 40  # per operation and generation mode
ARTIFACTS = Path(os.environ.get("TML_TEST_ARTIFACTS") or ROOT / "test-artifacts")
_DATA = Path(tempfile.mkdtemp(prefix="tml-fuzz-"))
_STORAGE = Storage(database_url(None, _DATA))
_SERVICE = Service(_STORAGE, FakeHangar(2, flowing=False), ServiceOptions(stop_timeout=10))
_SERVICE.upload("short.xml", SHORT)  # something to find
# Schemathesis calls the application as http://testserver.
schema = schemathesis.openapi.from_asgi("/openapi.json",
                                        create_app(_SERVICE, hosts=["testserver"]))
calls: list[str] = []
fuzzed: set[int] = set()  # the fuzzer's test items (one per operation) run in this process
FUZZER = "test_the_api_answers_any_input_without_a_server_error"


@atexit.register
def _stop_the_service() -> None:
    # At the process's end, not the module's: pytest-xdist may hand this module's tests to
    # a worker between other modules' tests, and a module's teardown runs at each switch.
    _SERVICE.stop()
    _STORAGE.close()
    shutil.rmtree(_DATA, ignore_errors=True)


@schema.parametrize()
@settings(max_examples=EXAMPLES, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
def test_the_api_answers_any_input_without_a_server_error(case: schemathesis.Case,
                                                          request: pytest.FixtureRequest) -> None:
    fuzzed.add(id(request.node))
    response = case.call()
    calls.append(f"{case.method} {case.path}")
    assert "Traceback" not in response.text
    # A request valid by the document may still be refused by the language or the
    # verifier (an XML body that is no mission, an infeasible run): 422, documented.
    case.validate_response(response, excluded_checks=[positive_data_acceptance])


def test_the_fuzzer_called_every_operation(request: pytest.FixtureRequest) -> None:
    if not calls:
        pytest.skip("the fuzzing test was not run")
    items = [item for item in request.session.items if item.name.startswith(FUZZER)]
    if len(fuzzed) < len(items):  # pytest-xdist spread the operations over its workers
        pytest.skip(f"{len(fuzzed)} of the fuzzer's {len(items)} operations ran in this "
                    "worker: run this file on its own to count them all")
    operations = {f"{method.upper()} {path}" for path, methods in
                  schema.raw_schema["paths"].items() for method in methods}
    assert set(calls) >= operations  # and undocumented methods, answered 405
    assert len(calls) >= len(operations) * 10, f"only {len(calls)} calls"
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    counted = Counter(calls)
    (ARTIFACTS / "serve-fuzz.txt").write_text(
        f"{len(calls)} calls of {len(operations)} operations\n"
        + "".join(f"{n:6d} {operation}\n" for operation, n in sorted(counted.items())))
