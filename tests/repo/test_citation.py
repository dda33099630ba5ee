"""CITATION.cff is valid Citation File Format 1.2.0 and agrees with the repository.

The schema (cff-schema-1.2.0.json) is the Citation File Format project's schema.json of release
1.2.0 (CC-BY-4.0), committed so the check needs no network.
"""
import json
import pathlib
import re

import pytest

yaml = pytest.importorskip("yaml", reason="python3-yaml is not installed")
jsonschema = pytest.importorskip(
    "jsonschema", reason="python3-jsonschema is not installed (scripts/setup-deps.sh installs it)")

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent.parent


def load_citation():
    # CFF is YAML 1.2; safe_load reads this file's subset the same way.
    with open(ROOT / "CITATION.cff", encoding="utf-8") as f:
        return yaml.safe_load(f)


def test_citation_matches_the_cff_1_2_0_schema():
    schema = json.loads((HERE / "cff-schema-1.2.0.json").read_text(encoding="utf-8"))
    validator = jsonschema.Draft7Validator(schema, format_checker=jsonschema.FormatChecker())
    errors = sorted(validator.iter_errors(load_citation()), key=lambda e: list(e.path))
    assert not errors, "\n".join(f"{list(e.path)}: {e.message}" for e in errors)


def test_citation_names_the_license_file_and_the_project_version():
    cff = load_citation()
    assert cff["license"] == "MIT"
    assert (ROOT / "LICENSE").read_text(encoding="utf-8").startswith("MIT License")
    cmake = (ROOT / "CMakeLists.txt").read_text(encoding="utf-8")
    version = re.search(r"project\(activefoam VERSION ([0-9.]+)", cmake).group(1)
    assert str(cff["version"]) == version, "CITATION.cff's version differs from CMakeLists.txt's"


def test_citation_references_the_paper_the_model_implements():
    titles = [r["title"] for r in load_citation().get("references", [])]
    assert "Active foam dynamics of tissue spheroid fusion" in titles
