// The Mapping page: BEGIN MAP / END MAP (MANUAL only, the robot decides), the save/discard dialog, map
// selection (switches the active map). The live map comes through the shared map view (map_version).
"use strict";

(function () {
  const $ = (id) => document.getElementById(id);
  const A = window.ATEMR;
  const toggle = $("mapping-toggle"), dialog = $("save-dialog"), select = $("map-select");

  A.onState((s) => {
    toggle.textContent = s.mapping ? "END MAP" : "BEGIN MAP";
    toggle.classList.toggle("on", !!s.mapping);
    if (s.active_map && select.value !== s.active_map && document.activeElement !== select) {
      if ([...select.options].some((o) => o.value === s.active_map)) select.value = s.active_map;
    }
  });

  toggle.addEventListener("click", async () => {
    if (A.state.mapping) {
      const ack = await A.command("mapping_end");
      if (ack.ok) { $("save-name").value = ""; dialog.showModal(); }
    } else {
      await A.command("mapping_begin");
    }
  });

  $("save-form").addEventListener("submit", async (e) => {
    e.preventDefault();
    const action = e.submitter ? e.submitter.value : "save";
    if (action === "discard") {
      const ack = await A.command("map_discard");
      if (ack.ok) dialog.close();
      return;
    }
    const name = $("save-name").value.trim();
    const ack = await A.command("map_save", { name });
    if (ack.ok) { dialog.close(); setTimeout(() => location.reload(), 300); }
  });

  select.addEventListener("change", () => { if (select.value) A.command("map_select", { name: select.value }); });
})();
