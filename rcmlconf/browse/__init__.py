"""The RCML browser (paper §5, Fig. 5; §8, Fig. 9): an RXID panel in a web browser, linked one
way to the robots its sessions name, over the reference client.

`sources` reads the RXID and RCML files, `panel` turns them into what the page draws, `links`
into what each robot's session does, `bridge` runs those sessions for one page, `messages` is the
page's protocol, `security` who may use it, and `server` serves the page and its WebSocket.
"""
