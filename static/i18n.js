// The page's language (app/i18n.py): the catalog's translations of this code's messages, which the
// server puts on <html>; English, the messages' own language, needs none. t("Moving {way}…", {way})
// fills the {names} in after translating; `pybabel extract` finds each t("...") (app/locale/babel.cfg).
const messages = JSON.parse(document.documentElement.dataset.messages || "{}");

export function t(message, params = {}) {
  return (messages[message] || message).replace(/\{(\w+)\}/g, (whole, name) => (name in params ? params[name] : whole));
}
