"""Participant studies over HTTP: the experimenter's pages to create and edit a study, and the
participant's way through it without an account (consent, code, instructions, their trials'
questionnaires, completion code, withdrawal), carried by a signed cookie (`app.study.passes`)."""

from __future__ import annotations

import json
import math
from datetime import UTC, datetime
from typing import Annotated
from urllib.parse import quote

from anyio import from_thread
from fastapi import APIRouter, Depends, Form, HTTPException, Request
from fastapi.responses import HTMLResponse, RedirectResponse, Response
from fastapi.templating import Jinja2Templates

from app.client_limits import Limited
from app.cookies import clear_site_data, delete_cookie, read_cookie, set_cookie
from app.db.engine import truncate_wal
from app.deps import (
    ClockDep,
    DbSession,
    HubDep,
    MazesDep,
    SeatTokensDep,
    SettingsDep,
    SignupsDep,
    StudyFilesDep,
    TemplatesDep,
    WebhooksDep,
    experimenter_id,
)
from app.guard import csrf_protect
from app.i18n import Text
from app.security import InvalidToken, SeatTokens
from app.study.answers import asked, items, study_answers
from app.study.config import (
    QuestionKind,
    StudyConfig,
    StudyConfigError,
    StudyFiles,
    StudyOutcome,
    check_mazes,
    parse,
    template,
)
from app.study.enrolment import AfterTrial, Enrolment, EnrolmentError, StudyFull
from app.study.form import form_values, from_form
from app.study.lobby import (
    PRACTICE_REASON,
    AllPlayed,
    Ended,
    Lobby,
    LobbyError,
    Seated,
    TimedOut,
    TimeUp,
    Waiting,
    seat_of,
)
from app.study.overview import study_trials
from app.study.own_data import own_data
from app.study.passes import PANEL_COOKIE, PASS_COOKIE, ParticipantPasses
from app.study.roster import roster, roster_csv
from app.study.signups import SignupLimits, Step
from app.trial.lifecycle import live_trial_of
from app.web import speak_study


def study_language(request: Request, files: StudyFilesDep, name: str) -> None:
    speak_study(request, files, name)


# A participant's pages and messages are in their study's language (`app.i18n`), its refusals too.
router = APIRouter(dependencies=[Depends(study_language), Depends(csrf_protect)])
experimenter_router = APIRouter(
    prefix="/experimenter/studies", dependencies=[Depends(experimenter_id), Depends(csrf_protect)]
)


def get_passes(settings: SettingsDep) -> ParticipantPasses:
    return ParticipantPasses(settings.signing_key())


PassesDep = Annotated[ParticipantPasses, Depends(get_passes)]


def study_or_404(files: StudyFiles, name: str) -> StudyConfig:
    try:
        return files.load(name)
    except LookupError as err:
        raise HTTPException(404, str(err)) from None
    except StudyConfigError as err:
        raise HTTPException(
            503, Text("this study cannot run until the experimenter fixes it: {problem}", problem=err)
        ) from None


class OpenStudy:
    """The study a request names (404 where there is none): its file, enrolment and lobby."""

    def __init__(self, name: str, files: StudyFilesDep, db: DbSession, clock: ClockDep, mazes: MazesDep) -> None:
        self.config = study_or_404(files, name)
        self.enrolment = Enrolment(db, clock, self.config)
        self.files, self.db, self.clock, self.mazes = files, db, clock, mazes

    def lobby(self) -> Lobby:
        return Lobby(self.db, self.config, self.mazes.layouts(), self.clock.now_ns())


StudyDep = Annotated[OpenStudy, Depends(OpenStudy)]


class Participation(OpenStudy):
    """The participant a request comes from: their study, its enrolment and their record."""

    def __init__(
        self,
        name: str,
        request: Request,
        files: StudyFilesDep,
        passes: PassesDep,
        db: DbSession,
        clock: ClockDep,
        mazes: MazesDep,
        templates: TemplatesDep,
    ) -> None:
        super().__init__(name, files, db, clock, mazes)
        self.request, self.templates = request, templates
        cookie = read_cookie(request, PASS_COOKIE)
        try:
            study_pass = passes.verify(cookie or "")
            if study_pass.study != name:
                raise InvalidToken("another study's pass")
            self.enrolled = self.enrolment.get(study_pass.enrolment_id)
        except (InvalidToken, LookupError):
            raise HTTPException(
                403, Text("this browser has not joined the study yet: open /study/{name}", name=name)
            ) from None
        if self.enrolled.withdrawn_at is not None:
            raise HTTPException(410, Text("you have withdrawn from this study; thank you for your time"))
        self.code = self.enrolment.code(self.enrolled)
        db.commit()  # end the reads' transaction (rows stay loaded) so a route may `with db.begin()`

    def page(self, name: str, status: int = 200, **context: object) -> HTMLResponse:
        """A page of the participant's way, with their study and code."""
        return _page(self.templates, self.request, name, status, study=self.config, code=self.code, **context)


ParticipationDep = Annotated[Participation, Depends(Participation)]


MAX_JSON = 200_000  # characters of a study's JSON the editor takes
EXPERIMENTER_PAGES = {"list", "edit"}  # the others are the participant's way: no link out of it


def _page(templates: TemplatesDep, request: Request, name: str, status: int = 200, **context: object) -> HTMLResponse:
    context = {"in_flow": name not in EXPERIMENTER_PAGES, **context}
    return templates.TemplateResponse(request, f"study/{name}.html", context, status_code=status)


# -- the participant ------------------------------------------------------------------------
def _busy(templates: TemplatesDep, request: Request, config: StudyConfig, limited: Limited) -> HTMLResponse:
    """The page for a sign-up over the study's rate: when to come back."""
    seconds = limited.retry_after_s
    response = _page(
        templates, request, "busy", status=429, study=config, seconds=seconds, minutes=math.ceil(seconds / 60)
    )
    response.headers["Retry-After"] = str(limited.retry_after_s)
    return response


def _address(request: Request) -> str:
    return request.client.host if request.client else ""


@router.get("/study/{name}", response_class=HTMLResponse)
def information(name: str, request: Request, study: StudyDep, passes: PassesDep, templates: TemplatesDep) -> Response:
    config, enrolment = study.config, study.enrolment
    try:
        study_pass = passes.verify(read_cookie(request, PASS_COOKIE) or "")
        enrolled = enrolment.get(study_pass.enrolment_id) if study_pass.study == name else None
    except (InvalidToken, LookupError):
        enrolled = None
    if config.panel is not None and config.panel.carried_by(request.query_params):
        # A panel's link: its identifiers are kept (with the participant, or until they consent)
        # and the address bar is cleaned of them at once.
        response = RedirectResponse(f"/study/{name}", status_code=303)
        ids = config.panel.read(request.query_params)
        if ids is not None and enrolled is not None:
            enrolment.set_panel(enrolled, ids)
            study.db.commit()
        elif ids is not None:
            set_cookie(response, request, PANEL_COOKIE, passes.issue_panel(name, ids), path="/study")
        return response
    if enrolled is not None:
        return RedirectResponse(f"/study/{name}/me", status_code=303)
    if enrolment.full():
        return _page(templates, request, "full", study=config)
    if config.closed(datetime.now(UTC)):
        return _page(templates, request, "closed", status=410, study=config)
    return _page(templates, request, "consent", study=config)


@router.post("/study/{name}/consent", response_class=HTMLResponse)
def consent(
    name: str,
    request: Request,
    study: StudyDep,
    passes: PassesDep,
    signups: SignupsDep,
    templates: TemplatesDep,
    choice: str = Form(pattern="^(agree|decline)$"),
    consent_version: str = Form(max_length=40),
) -> Response:
    config, enrolment = study.config, study.enrolment
    if config.closed(datetime.now(UTC)):
        return _page(templates, request, "closed", status=410, study=config)
    if consent_version != config.consent.version:
        error = Text("the information changed while the page was open: please read it again")
        return _page(templates, request, "consent", status=409, study=config, error=error)
    try:
        signups.take(Step.consent, name, _address(request))
    except Limited as limited:
        return _busy(templates, request, config, limited)
    try:
        with study.db.begin():
            if choice == "decline":
                enrolment.decline()
            else:
                enrolled = enrolment.consent(passes.panel_of(read_cookie(request, PANEL_COOKIE) or "", name))
    except StudyFull:
        return _page(templates, request, "full", status=409, study=config)
    if choice == "decline":
        response: Response = _page(templates, request, "declined", study=config)
    else:
        response = RedirectResponse(f"/study/{name}/code", status_code=303)
        set_cookie(response, request, PASS_COOKIE, passes.issue(name, enrolled.enrolment_id), path="/study")
    delete_cookie(response, request, PANEL_COOKIE, path="/study")  # stored with the participant, or declined: not kept
    return response


@router.get("/study/{name}/code", response_class=HTMLResponse)
def code_page(me: ParticipationDep, error: str | None = None) -> HTMLResponse:
    return me.page("code", real_name=me.enrolled.real_name, error=error)


@router.post("/study/{name}/name")
def real_name(me: ParticipationDep, real_name: str = Form("", max_length=200)) -> RedirectResponse:
    try:
        with me.db.begin():
            me.enrolment.set_real_name(me.enrolled, real_name)
    except EnrolmentError as err:
        return RedirectResponse(f"/study/{me.config.name}/code?error={quote(str(err))}", status_code=303)
    return RedirectResponse(f"/study/{me.config.name}/instructions", status_code=303)


@router.get("/study/{name}/instructions", response_class=HTMLResponse)
def instructions(me: ParticipationDep) -> HTMLResponse:
    return me.page("instructions")


@router.get("/study/{name}/me", response_class=HTMLResponse)
def my_study(me: ParticipationDep, seats: SeatTokensDep, error: str | None = None, saved: bool = False) -> HTMLResponse:
    trials = me.enrolment.trials(me.enrolled)
    return me.page(
        "me",
        trials=trials,
        answered=me.enrolment.answered(me.enrolled),
        unplayed=me.enrolment.unplayed(trials),
        enrolled=me.enrolled,
        practice_reason=PRACTICE_REASON,
        seat=_live_seat(me, seats),
        error=error,
        saved=saved,
    )


@router.get("/study/{name}/me/data.json")
def my_data(me: ParticipationDep) -> Response:
    """Everything recorded about the participant, as a JSON download (`app.study.own_data`)."""
    data = own_data(me.enrolment, me.enrolled, me.code)
    return Response(
        json.dumps(data, indent=1),
        media_type="application/json",
        headers={"Content-Disposition": f'attachment; filename="{me.config.name}-{me.code}.json"'},
    )


@router.get("/study/{name}/lobby", response_class=HTMLResponse)
def lobby_page(me: ParticipationDep) -> HTMLResponse:
    lobby = me.lobby()
    return me.page(
        "lobby",
        practice=lobby.needs_practice(me.enrolled),
        number=lobby.played(me.enrolled) + 1,  # the practice not counted
    )


def _enter_lobby(signups: SignupLimits, study: str, address: str) -> None:
    try:
        signups.take(Step.lobby, study, address)
    except Limited as limited:
        raise HTTPException(
            429,
            Text(
                "more people are joining the lobby than it takes at once; trying again in {seconds} s",
                seconds=limited.retry_after_s,
            ),
            headers={"Retry-After": str(limited.retry_after_s)},
        ) from None


@router.post("/study/{name}/lobby")
def lobby_poll(
    me: ParticipationDep,
    seats: SeatTokensDep,
    hub: HubDep,
    signups: SignupsDep,
    webhooks: WebhooksDep,
) -> dict[str, object]:
    """The lobby page's poll (about once a second): the seat's link once paired, else the count
    waiting. Entering the lobby (a poll while neither waiting nor in a live trial) counts against
    the lobby's rates; over one, 429 and the page asks again."""
    lobby = me.lobby()
    with me.db.begin():
        if me.enrolled.lobby_since is None and live_trial_of(me.db, (me.enrolled.participant_id,)) is None:
            _enter_lobby(signups, me.config.name, _address(me.request))
        state = lobby.poll(me.enrolled, datetime.now(UTC))
        match state:  # the ends of a way that the lobby finds, recorded before anyone is told
            case TimedOut():
                outcome = me.enrolment.end(me.enrolled, StudyOutcome.no_partner, lobby.finished(me.enrolled))
            case TimeUp():
                outcome = me.enrolment.end(me.enrolled, StudyOutcome.timed_out, lobby.finished(me.enrolled))
            case Ended():
                outcome = me.enrolment.outcome(me.enrolled) or StudyOutcome.completed
    done = f"/study/{me.config.name}/done"
    match state:
        case Seated(trial_id, role, paired_now):
            if paired_now:
                # Run it now, so its join deadline (in its log) runs even if no seat comes.
                from_thread.run(hub.get, trial_id)
                webhooks.paired(trial_id)
            return {"state": "seated", "role": role, "link": f"/play/{seats.issue(trial_id, role)}"}
        case Waiting(waiting):
            return {"state": "waiting", "waiting": waiting}
        case TimedOut(waited_s):
            return {"state": "timed_out", "waited_s": round(waited_s), "outcome": outcome, "next": done}
        case AllPlayed(trials, teams):
            return {"state": "all_played", "trials": trials, "teams": teams}
        case TimeUp() | Ended():
            return {"state": "ended", "outcome": outcome, "next": done}


@router.post("/study/{name}/lobby/leave")
def lobby_leave(me: ParticipationDep) -> RedirectResponse:
    """The lobby page's "Leave the lobby", and its beacon as the page closes: out of the lobby at
    once, so the next arrival is not paired with someone who has gone."""
    with me.db.begin():
        me.lobby().leave(me.enrolled)
    return RedirectResponse(f"/study/{me.config.name}/me", status_code=303)


def _live_seat(me: Participation, seats: SeatTokens) -> dict[str, object]:
    """The participant's live trial's seat (`link`), or none."""
    live = live_trial_of(me.db, (me.enrolled.participant_id,))
    if live is None:
        return {"trial_id": None, "link": None}
    role = seat_of(live, me.enrolled.participant_id).role
    return {"trial_id": live.id, "role": role, "link": f"/play/{seats.issue(live.id, role)}"}


@router.get("/study/{name}/seat")
def my_seat(me: ParticipationDep, seats: SeatTokensDep) -> dict[str, object]:
    """The participant's live trial's seat, or none: the seat page of a trial that is over asks, and
    follows the experimenter's restart of it to the new trial's seat."""
    return _live_seat(me, seats)


@router.get("/study/{name}/trials/{trial_id}/next")
def after_trial(me: ParticipationDep, trial_id: int) -> RedirectResponse:
    """The seat page's "Continue" once a trial is over: its questionnaire, or the lobby where there
    is nothing to rate (the practice, a trial a partner never opened), or the participant's page."""
    try:
        step = me.enrolment.after(me.enrolled, trial_id)
    except EnrolmentError as err:
        raise HTTPException(404, err.args[0]) from err
    pages = {
        AfterTrial.questionnaire: f"trials/{trial_id}/questionnaire",
        AfterTrial.lobby: "lobby",
        AfterTrial.study_page: "me",
    }
    return RedirectResponse(f"/study/{me.config.name}/{pages[step]}", status_code=303)


@router.get("/study/{name}/trials/{trial_id}/questionnaire", response_class=HTMLResponse)
def questionnaire(me: ParticipationDep, trial_id: int) -> HTMLResponse:
    """Served only where an answer would be taken: a trial of theirs, played and over, not rated yet."""
    try:
        me.enrolment.questionnaire_due(me.enrolled, trial_id)
    except EnrolmentError as err:
        raise HTTPException(404, err.args[0]) from err
    return me.page("questionnaire", trial_id=trial_id, form={})


@router.post("/study/{name}/trials/{trial_id}/questionnaire")
async def answer(me: ParticipationDep, trial_id: int, request: Request) -> Response:
    form = {k: v for k, v in (await request.form()).items() if isinstance(v, str)}
    try:
        with me.db.begin():
            me.enrolment.answer(me.enrolled, trial_id, form)
    except EnrolmentError as err:
        return me.page("questionnaire", status=400, trial_id=trial_id, form=form, error=err.args[0])
    return RedirectResponse(f"/study/{me.config.name}/me?saved=true", status_code=303)


@router.post("/study/{name}/complete", response_class=HTMLResponse)
def complete(me: ParticipationDep, confirm: str = Form("", max_length=10)) -> Response:
    """ "I have finished": the plan played ends the way at once; anything short of it is said
    first and ends only once confirmed (a partial completion, or the outcome it is); with nothing
    played there is nothing to finish. The code is shown only once the end is committed."""
    lobby = me.lobby()
    with me.db.begin():
        outcome = me.enrolment.outcome(me.enrolled) or lobby.finishing(me.enrolled, datetime.now(UTC))
        finished = lobby.finished(me.enrolled)
        if outcome is None or (
            me.enrolled.completed_at is None and outcome is not StudyOutcome.completed and confirm != "yes"
        ):
            return me.page(
                "finish",
                outcome=outcome,
                finished=finished,
                live=live_trial_of(me.db, (me.enrolled.participant_id,)) is not None,
            )
        me.enrolment.end(me.enrolled, outcome, finished)
    return RedirectResponse(f"/study/{me.config.name}/done", status_code=303)


ONWARD_AFTER_S = 10  # the end page's countdown (which they may stop) before it sends the participant on


def onward(config: StudyConfig, completion: str | None) -> str | None:
    """Where the end page sends the participant: the panel's completion address with their code,
    else the study's `redirect_url`."""
    if config.panel is not None and completion is not None:
        address = config.panel.completion(completion)
        if address is not None:
            return address
    return None if config.redirect_url is None else str(config.redirect_url)


@router.get("/study/{name}/done", response_class=HTMLResponse)
def done_page(me: ParticipationDep) -> Response:
    """The end of a participant's way: how it ended, and that outcome's code (recorded already)."""
    outcome = me.enrolment.outcome(me.enrolled)
    if outcome is None:
        return RedirectResponse(f"/study/{me.config.name}/me", status_code=303)
    completion = me.config.code_for(outcome)
    return me.page(
        "done",
        outcome=outcome,
        completion=completion,
        onward=onward(me.config, completion),
        onward_after_s=ONWARD_AFTER_S,
    )


@router.post("/study/{name}/withdraw", response_class=HTMLResponse)
def withdraw(me: ParticipationDep, webhooks: WebhooksDep, confirm: str = Form("", max_length=10)) -> Response:
    if confirm != "yes":  # erasing is not undone: only on the box ticked beside the button
        error = Text("To withdraw, tick the box that says you want to, then press Withdraw.")
        return RedirectResponse(f"/study/{me.config.name}/me?error={quote(error)}#withdraw-from-study", status_code=303)
    with me.db.begin():
        ended = me.enrolment.outcome(me.enrolled)
        me.enrolment.withdraw(me.enrolled)
    truncate_wal(me.db.get_bind().engine)  # no copy of the erased text stays in SQLite's WAL file
    webhooks.withdrawal(me.config.name, me.code)
    # The withdrawal's code, for one whose way had not ended otherwise (that code they were given then).
    completion = me.config.code_for(StudyOutcome.withdrew) if ended is None else None
    response = me.page(
        "withdrawn",
        completion=completion,
        onward=onward(me.config, completion) if completion is not None else None,
        onward_after_s=ONWARD_AFTER_S,
    )
    delete_cookie(response, me.request, PASS_COOKIE, path="/study")
    clear_site_data(response)  # the browser keeps nothing of them: cookies, storage, cache
    return response


# -- the experimenter -----------------------------------------------------------------------
@experimenter_router.get("", response_class=HTMLResponse)
def study_list(
    request: Request, files: StudyFilesDep, templates: TemplatesDep, error: str | None = None
) -> HTMLResponse:
    return _page(templates, request, "list", studies=files.names(), error=error)


@experimenter_router.post("")
def create_study(files: StudyFilesDep, name: str = Form(max_length=80)) -> RedirectResponse:
    try:
        files.path(name)
        if name in files.names():
            raise StudyConfigError(f"a study named {name!r} exists: edit it")
        files.save(template(name))
    except (LookupError, StudyConfigError) as err:
        message = (
            "a study name is 1-80 lowercase letters, digits, '-' or '_'" if isinstance(err, LookupError) else str(err)
        )
        return RedirectResponse(f"/experimenter/studies?error={quote(message)}", status_code=303)
    return RedirectResponse(f"/experimenter/studies/{name}", status_code=303)


def _editor(
    templates: Jinja2Templates,
    request: Request,
    study: OpenStudy,
    text: str,
    values: dict[str, object],
    status: int = 200,
    **context: object,
) -> HTMLResponse:
    name, enrolment, lobby = study.config.name, study.enrolment, study.lobby()
    answers = study_answers(study.db, name)
    participants = enrolment.participants()
    # Each participant's trials against the plan: study trials played (the practice not counted), practised.
    progress = {e.id: (lobby.played(e), not lobby.needs_practice(e)) for e, _, _ in participants}
    return _page(
        templates,
        request,
        "edit",
        status=status,
        study=study.config,
        text=text,
        values=values,
        kinds=list(QuestionKind),
        outcomes_coded=[o for o in StudyOutcome if o is not StudyOutcome.completed],
        link=request.url_for("information", name=name),
        trials=study_trials(study.db, name),
        progress=progress,
        participants=participants,
        outcomes={e.id: enrolment.outcome(e) for e, _, _ in participants},
        answers=answers,
        questions=items(asked(study.files, name, answers)),
        **context,
    )


@experimenter_router.get("/{name}", response_class=HTMLResponse)
def edit_page(
    study: StudyDep,
    request: Request,
    templates: TemplatesDep,
    saved: int | None = None,
    paired: int | None = None,
    screened: str | None = None,
    error: str | None = None,
) -> HTMLResponse:
    text = study.config.model_dump_json(indent=2)
    values = form_values(study.config)
    return _editor(templates, request, study, text, values, saved=saved, paired=paired, screened=screened, error=error)


@experimenter_router.post("/{name}")
async def save_study(name: str, study: StudyDep, request: Request, templates: TemplatesDep) -> Response:
    """The editor's form, or (`config_json`) the study's JSON whole, for power users."""
    current, mazes = study.config, study.mazes
    form = {k: v for k, v in (await request.form()).items() if isinstance(v, str)}
    config_json = form.get("config_json")
    text = current.model_dump_json(indent=2) if config_json is None else config_json  # shown again on an error
    values = form_values(current)
    try:
        if config_json is not None:
            if len(config_json) > MAX_JSON:
                raise StudyConfigError(f"the JSON is {len(config_json)} characters; at most {MAX_JSON}")
            config = parse(config_json)
        else:
            values, made, problem = from_form(current, form)
            if made is None:
                raise StudyConfigError(problem)
            config = made
        if config.name != name:
            raise StudyConfigError(f"the name is {name!r}; make a new study to use another name")
        bundled = {m for m in mazes.names() if mazes.library.source(m) == "bundled"}
        check_mazes(config, bundled, set(mazes.names()))
    except StudyConfigError as err:
        return _editor(templates, request, study, text, values, status=400, error=str(err))
    saved = study.files.save(config)
    return RedirectResponse(f"/experimenter/studies/{name}?saved={saved.version}", status_code=303)


@experimenter_router.get("/{name}/participants.csv")
def participants_csv(name: str, study: StudyDep) -> Response:
    """The study's roster for paying its participants (`app.study.roster`)."""
    return Response(
        roster_csv(roster(study.enrolment, datetime.now(UTC))),
        media_type="text/csv",
        headers={"Content-Disposition": f'attachment; filename="{name}-participants.csv"'},
    )


@experimenter_router.get("/{name}/lobby")
def lobby_view(study: StudyDep) -> dict[str, object]:
    """Who waits in the study's lobby now, for the study page's live view (polled)."""
    return {"waiting": study.lobby().view(datetime.now(UTC))}


@experimenter_router.post("/{name}/screen-out")
def screen_out(name: str, study: StudyDep, code: str = Form(max_length=80)) -> RedirectResponse:
    """The experimenter screens a participant out: their way ends with that outcome (and its code,
    which their pages show from then on); a live trial of theirs is the experimenter's to stop."""
    enrolment, lobby = study.enrolment, study.lobby()
    try:
        with study.db.begin():
            enrolled = enrolment.by_code(code)
            before = enrolment.outcome(enrolled)
            if before is not None:
                raise EnrolmentError(f"{code.strip()}'s way had already ended: {before}")
            enrolment.end(enrolled, StudyOutcome.screened_out, lobby.finished(enrolled))
    except (LookupError, EnrolmentError) as err:
        return RedirectResponse(f"/experimenter/studies/{name}?error={quote(str(err))}", status_code=303)
    return RedirectResponse(f"/experimenter/studies/{name}?screened={quote(code.strip())}", status_code=303)


@experimenter_router.post("/{name}/pair")
def pair_by_hand(
    name: str,
    study: StudyDep,
    hub: HubDep,
    webhooks: WebhooksDep,
    a: str = Form(max_length=80),
    b: str = Form(max_length=80),
) -> RedirectResponse:
    """Pair two of the study's participants (by code) now, by the lobby's rules."""
    lobby = study.lobby()
    try:
        with study.db.begin():
            first, second = (study.enrolment.by_code(code) for code in (a, b))
            trial = lobby.pair(first, second)
            trial_id = trial.id
    except (LookupError, LobbyError) as err:
        return RedirectResponse(f"/experimenter/studies/{name}?error={quote(str(err))}", status_code=303)
    from_thread.run(hub.get, trial_id)
    webhooks.paired(trial_id)
    return RedirectResponse(f"/experimenter/studies/{name}?paired={trial_id}", status_code=303)
