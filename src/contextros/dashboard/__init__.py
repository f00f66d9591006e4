"""`contextros dashboard`: a live web page of one robot's context, or several robots'.

`model` keeps what the page shows, as pure logic fed with plain values (bounded: an open page
costs the same after an hour as after a minute); `contextros.ros.dashboard_node` feeds it from
the protocol's topics and the manager's query service; `server` serves the page and pushes
each change over a WebSocket (aiohttp), so a switch shows within milliseconds.
"""
