"""The repository's LICENSE (MIT) and CITATION.cff (software, citing the ICCV 2003 paper), and their
agreement with the BibTeX every dataset card carries."""

from __future__ import annotations

import re
from pathlib import Path

import yaml

from silpose.datagen.card import DATA_LICENSE, PAPER_BIBTEX

ROOT = Path(__file__).resolve().parents[1]
AUTHORS = [("Grauman", "Kristen"), ("Shakhnarovich", "Gregory"), ("Darrell", "Trevor")]


def test_license_is_mit():
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("MIT License\n\nCopyright (c) ")
    assert "Permission is hereby granted, free of charge" in text and 'THE SOFTWARE IS PROVIDED "AS IS"' in text


def test_citation_cff_describes_the_software_and_cites_the_paper():
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0" and cff["type"] == "software" and cff["license"] == "MIT"
    assert cff["title"].startswith("silpose") and cff["authors"] and cff["message"]
    assert str(cff["version"]) == re.search(r'^version = "(.+)"', (ROOT / "pyproject.toml").read_text(), re.M)[1]
    (paper,) = cff["references"]
    assert paper["type"] == "conference-paper"
    assert paper["title"] == "Inferring 3D Structure with a Statistical Image-Based Shape Model"
    assert [(a["family-names"], a["given-names"]) for a in paper["authors"]] == AUTHORS
    assert (paper["year"], paper["start"], paper["end"]) == (2003, 641, 647)
    assert "ICCV" in paper["collection-title"]


def test_card_bibtex_agrees_with_citation_cff():
    authors = re.search(r"author\s*=\s*\{(.+)\},", PAPER_BIBTEX)[1]
    assert authors == " and ".join(f"{f}, {g}" for f, g in AUTHORS)
    assert re.search(r"pages\s*=\s*\{641--647\}", PAPER_BIBTEX) and re.search(r"year\s*=\s*\{2003\}", PAPER_BIBTEX)
    assert PAPER_BIBTEX.count("{") == PAPER_BIBTEX.count("}")  # balanced braces: BibTeX parses
    assert DATA_LICENSE == "cc-by-4.0"
