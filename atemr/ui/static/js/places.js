// The Places panel shared by Control and Mapping: the "Go to" list (a button per named place of the active
// map: switches to AUTO when needed, then sends the robot there), and editing the places: ADD PLACE makes
// the next tap on the map a place (drag for its heading) and asks its name; each place can be moved (tap
// the map again), renamed or deleted (a second tap confirms). The robot checks every change and stores it
// with the map; a refusal is shown here with its reason.
"use strict";

(function () {
  const $ = (id) => document.getElementById(id);
  const A = window.ATEMR;
  const list = $("place-list");
  if (!list || !A.map) return;
  const form = $("place-form"), nameIn = $("place-name"), kindIn = $("place-kind"), status = $("place-status");
  const addBtn = $("place-add");
  let editing = null;  // {pose, previous}: the place being added or changed, waiting for its name
  let picking = null;  // null | {previous}: the next tap on the map is a place's pose
  let saved = null;    // the map view's own tap handler while a place is picked
  let known = "";

  function say(text, ok) {
    status.textContent = text || "";
    status.classList.toggle("error", ok === false);
  }

  function stopPicking() {
    if (!picking) return;
    picking = null;
    A.map.onPose = saved;
    A.map.commandMode = false;
    addBtn.classList.remove("on");
  }

  function pick(previous) {
    if (picking) { stopPicking(); say(""); return; }
    saved = A.map.onPose;
    picking = { previous };
    A.map.commandMode = true;
    addBtn.classList.toggle("on", previous === null);
    say(previous === null ? "Tap the map where the place is; drag from there for the way the robot faces."
                          : `Tap the map where ${previous} is now; drag for the heading.`);
    A.map.onPose = (pose) => {
      const was = picking;
      stopPicking();
      edit(pose, was.previous);
    };
  }

  function edit(pose, previous, kind) {
    editing = { pose, previous };
    A.map.pending = pose;
    A.map.draw();
    nameIn.value = previous || "";
    kindIn.value = kind || (previous && placeNamed(previous) ? placeNamed(previous).kind : "place");
    form.hidden = false;
    nameIn.focus();
    say(`At x ${pose.x_m.toFixed(2)} m, y ${pose.y_m.toFixed(2)} m: name it and SAVE.`);
  }

  function endEdit() {
    editing = null;
    form.hidden = true;
    A.map.pending = null;
    A.map.draw();
  }

  function placeNamed(name) {
    return (A.state.places || []).find((p) => p.name === name);
  }

  async function goTo(name) {
    if (A.state.mode !== "AUTO") {
      const ack = await A.command("mode", { mode: "AUTO" }, "go_to_place");
      if (!ack.ok) { say(ack.reason, false); return; }
      await A.until((s) => s.mode === "AUTO", 3000);
    }
    const ack = await A.command("go_to_place", { name });
    say(ack.ok ? `Going to ${name}…` : ack.reason, ack.ok ? undefined : false);
  }

  async function remove(btn, name) {
    if (btn.dataset.sure !== "1") {  // a second tap confirms: nothing is deleted by one slip
      btn.dataset.sure = "1";
      btn.textContent = "SURE?";
      setTimeout(() => { btn.dataset.sure = ""; btn.textContent = "DELETE"; }, 4000);
      return;
    }
    const ack = await A.command("place_delete", { name });
    say(ack.ok ? `${name} deleted.` : ack.reason, ack.ok ? undefined : false);
  }

  function button(text, cls, onClick) {
    const b = document.createElement("button");
    b.type = "button";
    b.textContent = text;
    b.className = cls;
    b.addEventListener("click", () => onClick(b));
    return b;
  }

  function render(places) {
    list.innerHTML = "";
    for (const p of places) {
      const li = document.createElement("li");
      li.className = "row";
      li.dataset.place = p.name;
      const go = button(p.name, "place-go primary", () => goTo(p.name));
      go.dataset.drive = "";
      go.title = `go to ${p.name}`;
      li.append(go,
        button("MOVE", "place-move", () => pick(p.name)),
        button("RENAME", "place-rename", () => edit({ x_m: p.x_m, y_m: p.y_m, yaw_rad: p.yaw_rad }, p.name, p.kind)),
        button("DELETE", "place-delete", (b) => remove(b, p.name)));
      if (p.kind === "dock") { const s = document.createElement("span"); s.className = "hint"; s.textContent = "dock"; li.append(s); }
      list.appendChild(li);
    }
    $("place-none").hidden = places.length > 0;
  }

  A.onState((s) => {
    const places = Array.isArray(s.places) ? s.places : [];
    const key = JSON.stringify(places);
    if (key !== known) { known = key; render(places); }
  });

  addBtn.addEventListener("click", () => { endEdit(); pick(null); });
  $("place-cancel").addEventListener("click", () => { endEdit(); say(""); });
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    if (!editing) return;
    const name = nameIn.value.trim();
    const body = { name, kind: kindIn.value, ...editing.pose, previous: editing.previous };
    const ack = await A.command("place_save", body);
    if (ack.ok) { endEdit(); say(`${name} saved.`); } else say(ack.reason, false);
  });
})();
