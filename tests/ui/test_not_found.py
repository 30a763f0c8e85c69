"""An address that is not a page: the dashboard's own page in plain words with the way back (readable on a
phone), JSON for an API call, and what a view said is missing kept."""

from __future__ import annotations


def test_a_mistyped_address_is_a_page_with_the_way_back(alice):
    response = alice.get("/contorl")
    assert response.status_code == 404 and response.mimetype == "text/html"
    page = response.get_data(as_text=True)
    assert "This page does not exist" in page and 'href="/control"' in page
    assert 'name="viewport"' in page  # the dashboard's own layout: a phone does not zoom out to 980 px


def test_an_api_call_to_nowhere_answers_in_json(alice):
    response = alice.get("/api/nowhere", headers={"Accept": "application/json"})
    assert response.status_code == 404
    assert response.get_json()["ok"] is False


def test_a_page_asked_the_wrong_way_says_so(alice):
    response = alice.get("/auth/logout")  # a form posts it
    assert response.status_code == 405 and "This page cannot do that" in response.get_data(as_text=True)


def test_what_a_view_said_is_missing_is_kept(alice):
    response = alice.get("/media/images/nothing-here.jpg")
    assert response.status_code == 404, response.status_code
    assert "This page does not exist" in response.get_data(as_text=True)
    assert "The address may be mistyped" not in response.get_data(as_text=True)
