"""The message catalogs (app/locale): every participant-facing message in the code is in the
template and translated, reviewed, in each language; a translation keeps its placeholders."""

from __future__ import annotations

import re

from babel.messages.extract import DEFAULT_KEYWORDS, extract_from_dir
from babel.messages.frontend import parse_mapping_cfg
from babel.messages.pofile import read_po

from app.i18n import LOCALE, Language, catalog
from bench.live import REPO

PLACEHOLDER = re.compile(r"\{\w+\}|%\(\w+\)[sd]")


def in_the_code() -> set[str]:
    """The messages `make messages` extracts (its keywords: `Text` and the scripts' `t`)."""
    with (LOCALE / "babel.cfg").open() as cfg:
        methods, options = parse_mapping_cfg(cfg)
    keywords = {**DEFAULT_KEYWORDS, "Text": None, "t": None}
    found = extract_from_dir(REPO, methods, options, keywords)
    return {m if isinstance(m, str) else m[0] for _, _, m, _, _ in found}


def ids(messages) -> set[str]:
    return {m.id if isinstance(m.id, str) else m.id[0] for m in messages if m.id}


def test_every_message_in_the_code_is_in_the_template_and_translated_in_each_language():
    code = in_the_code()
    with (LOCALE / "messages.pot").open("rb") as pot:
        template = ids(read_po(pot))
    assert code == template, ("run `make messages`", sorted(code ^ template)[:10])
    for language in Language:
        if language == Language.en:
            continue
        translated = ids(m for m in catalog(language) if m.string and all(m.string) and not m.fuzzy)
        assert not code - translated, (language, sorted(code - translated)[:10])


def test_a_translation_keeps_the_placeholders_of_its_message():
    for language in (lang for lang in Language if lang != Language.en):
        for m in catalog(language):
            original = m.id if isinstance(m.id, str) else m.id[-1]  # a plural's: those of its plural form
            for string in (m.string,) if isinstance(m.string, str) else m.string:
                assert sorted(PLACEHOLDER.findall(string)) == sorted(PLACEHOLDER.findall(original)), (language, m.id)
