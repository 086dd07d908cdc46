"""Everything before the first ADS connection: local NetId, route, target NetId.

A target that does not answer or refuses the route is the user's to fix (wrong
host, wrong password), so failures here become one-line `TargetError`s naming
the configuration key; the password never appears in them. A `TargetError`
is also what the IOC waits out at start (the PLC may come later); every
other `UserError` (a password variable that is not set) stops it.
"""

from __future__ import annotations

from fastcs_ethercat.ads.client import (
    AdsError,
    add_route,
    discover_net_id,
    local_ip_towards,
    set_local_net_id,
)
from fastcs_ethercat.ads.netid import AmsNetId
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.config import IocConfig


class TargetError(UserError):
    """The target cannot be reached, or refused what was asked of it."""


async def prepare_target(config: IocConfig) -> AmsNetId:
    """Set our NetId, add our route if asked, return the target's NetId.

    The NetId comes from the configuration or, when not given, from UDP
    discovery (48899). Our own NetId defaults to `<local IP>.1.1`, the one
    AdsLib derives, so the route we add is the one AdsLib will use.
    """
    host = config.target_host
    if config.local_net_id is not None:
        set_local_net_id(config.local_net_id)
    try:
        if config.route is not None:
            local_ip = local_ip_towards(host)
            await add_route(
                host,
                local_net_id=config.local_net_id or f"{local_ip}.1.1",
                host_address=config.route.host_address or local_ip,
                user=config.route.user,
                password=config.route.password(),
                route_name=config.route.route_name,
            )
        if config.ams_net_id is not None:
            return AmsNetId.parse(config.ams_net_id)
        return await discover_net_id(host)
    except AdsError as error:
        where = "route" if error.operation == "add route" else "target"
        raise TargetError(str(error), where=where) from None
    except OSError as error:
        raise TargetError(
            f"cannot reach {host}: {error.strerror or error}", where="target"
        ) from None
