"""Participant studies: a named, versioned configuration in the data directory (`config`), the
participants who consent to it under a pseudonym, their questionnaires and withdrawal (`enrolment`),
and the signed pass that carries a participant from page to page without an account (`passes`).

Not the LDH localization studies of `app.localization_study`: those show recorded dialogs; these run trials."""
