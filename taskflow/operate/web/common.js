// taskflow view: what the run page (view.js) and the campaign page (campaign.js) share; loaded before either.
"use strict";

const $ = (id) => document.getElementById(id);

// the page's token, from the address the server printed (…/?token=…): sent with every request
const TOKEN = new URLSearchParams(window.location.search).get("token") || "";
const authHeaders = () => (TOKEN ? { Authorization: `Bearer ${TOKEN}` } : {});
const withToken = (url) => (TOKEN ? `${url}${url.includes("?") ? "&" : "?"}token=${encodeURIComponent(TOKEN)}` : url);

// a table cell holding text (never markup: the record's strings are untrusted)
function cell(tr, text, cls) {
  const td = document.createElement("td");
  td.textContent = text;
  if (cls) td.className = cls;
  tr.appendChild(td);
  return td;
}
