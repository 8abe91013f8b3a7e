"""The participant's language. Every participant-facing message comes from the catalogs in
app/locale (gettext's .po, read with Babel; English, the messages' own language, needs none):
the pages through Jinja2's i18n extension, the browser code through the catalog's messages its
scripts use (`browser_messages`, put on each page for static/i18n.js) and the server's own
messages a page shows (`Text`). A study chooses its language (`StudyConfig.language`); the
request's is `request.state.language`, English where nothing set it. docs/study.md: adding one."""

from __future__ import annotations

from enum import StrEnum
from functools import cache
from gettext import GNUTranslations, NullTranslations
from io import BytesIO
from pathlib import Path
from typing import Any

from babel.messages.catalog import Catalog
from babel.messages.mofile import write_mo
from babel.messages.pofile import read_po
from jinja2 import Environment, pass_context
from jinja2.runtime import Context
from starlette.requests import HTTPConnection

LOCALE = Path(__file__).resolve().parent / "locale"


class Language(StrEnum):
    en = "en"  # the messages' own: no catalog
    de = "de"


@cache
def catalog(language: Language) -> Catalog:
    """The language's catalog, read from its .po (the one source: nothing compiled is kept)."""
    with (LOCALE / language / "LC_MESSAGES" / "messages.po").open("rb") as po:
        return read_po(po, locale=str(language))


@cache
def translations(language: Language) -> NullTranslations:
    """gettext's translations for `language` (fuzzy entries left out: English until reviewed)."""
    if language == Language.en:
        return NullTranslations()
    mo = BytesIO()
    write_mo(mo, catalog(language))
    mo.seek(0)
    return GNUTranslations(mo)


@cache
def browser_messages(language: Language) -> dict[str, str]:
    """The translations of the messages static/*.js uses (the catalog knows where each is used)."""
    if language == Language.en:
        return {}
    return {
        str(m.id): str(m.string)
        for m in catalog(language)
        if m.id and m.string and not m.fuzzy and any(path.startswith("static/") for path, _ in m.locations)
    }


def language_of(conn: HTTPConnection) -> Language:
    language: Language = getattr(conn.state, "language", Language.en)
    return language


class Text(str):
    """A message of the server's that a participant may read: the English text as a str (logs,
    JSON replies) and `in_(language)` where a page shows it. Its msgid is a str.format template;
    `make messages` extracts it."""

    message: str
    params: dict[str, Any]

    def __new__(cls, message: str, **params: Any) -> Text:
        text = super().__new__(cls, message.format(**params))
        text.message, text.params = message, params
        return text

    def in_(self, language: Language) -> str:
        return translations(language).gettext(self.message).format(**self.params)


def said(message: object, language: Language) -> str:
    """`message` in `language`: a `Text`, or a message of the catalog's (anything else, such as an
    experimenter's own words, as it is)."""
    return message.in_(language) if isinstance(message, Text) else translations(language).gettext(str(message))


@pass_context
def _gettext(context: Context, message: str) -> str:
    return translations(context.get("lang", Language.en)).gettext(message)


@pass_context
def _ngettext(context: Context, singular: str, plural: str, n: int) -> str:
    return translations(context.get("lang", Language.en)).ngettext(singular, plural, n)


@pass_context
def _said(context: Context, message: object) -> str:
    return said(message, context.get("lang", Language.en))


def install(env: Environment) -> None:
    """`_()`, `ngettext()`, `{% trans %}` and `| said` (a server's message) in the page's `lang`."""
    env.filters["said"] = _said
    env.add_extension("jinja2.ext.i18n")
    env.policies["ext.i18n.trimmed"] = True  # a message's line breaks and indents are not part of it
    env.install_gettext_callables(_gettext, _ngettext, newstyle=True)  # type: ignore[attr-defined]
